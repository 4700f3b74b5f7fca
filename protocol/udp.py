"""Byte codecs of the sensor-fusion UDP protocols (CONTRACT.md §3, after seed 002).

- INPUT_PROTOCOL: interface-modules → listener. A 5-byte header (SENSOR_TYPE uint8, SEQ_NO
  uint16, N_INT uint8, N_DOUBLE uint8), then N_INT int32 and N_DOUBLE binary64 values.
- OUTPUT_PROTOCOL: listener → OBCU, 18 bytes (SEQ_NO uint16, EPOCH double, FU_ARC_LEN double).
- ACK: OBCU → listener, 2 bytes (the last SEQ_NO received).

Everything is little-endian. Decoding raises only :class:`~protocol.MalformedDatagramError`
subclasses; encoding raises only :class:`~protocol.DatagramEncodeError`.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from enum import IntEnum

from protocol._exceptions import (
    CountMismatchError,
    DatagramEncodeError,
    LengthMismatchError,
    TruncatedDatagramError,
    UnknownSensorTypeError,
)

__all__ = [
    "ACK_SIZE",
    "EXPECTED_COUNTS",
    "INPUT_HEADER_SIZE",
    "OUTPUT_SIZE",
    "SEQ_MODULO",
    "Ack",
    "InputPacket",
    "OutputPacket",
    "SensorType",
    "decode_ack",
    "decode_input",
    "decode_output",
    "encode_ack",
    "encode_input",
    "encode_output",
]

SEQ_MODULO = 65536
INPUT_HEADER_SIZE = 5
OUTPUT_SIZE = 18
ACK_SIZE = 2

_HEADER = struct.Struct("<BHBB")
_OUTPUT = struct.Struct("<Hdd")
_ACK = struct.Struct("<H")
_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1


class SensorType(IntEnum):
    IMU = 1
    ODOMETER = 2
    GPS = 3
    GROUND_TRUTH = 8
    STROBE = 9
    STOP = 10


EXPECTED_COUNTS: dict[SensorType, tuple[int, int]] = {
    SensorType.IMU: (0, 6),
    SensorType.ODOMETER: (0, 2),
    SensorType.GPS: (0, 3),
    SensorType.GROUND_TRUTH: (0, 4),
    SensorType.STROBE: (0, 1),
    SensorType.STOP: (0, 0),
}
"""(N_INT, N_DOUBLE) fixed for each sensor type."""

_MESSAGES = {
    sensor_type: struct.Struct(f"{_HEADER.format}{n_int}i{n_double}d")
    for sensor_type, (n_int, n_double) in EXPECTED_COUNTS.items()
}
"""Each sensor type's whole datagram, header and values (compiled once)."""
_SENSOR_TYPES = {int(sensor_type): sensor_type for sensor_type in SensorType}
"""SENSOR_TYPE values to members: a dict look-up costs a tenth of ``SensorType(value)`` (its
``EnumType.__call__``), on every datagram the listener receives."""
_FIELDS_AFTER_HEADER = 4


@dataclass(frozen=True)
class InputPacket:
    """One INPUT_PROTOCOL datagram.

    ``doubles`` by type: IMU acc x, y, z [m/s²] and gyro x, y, z [rad/s] (body frame, x forward,
    y right, z down); ODOMETER speed and σ [m/s]; GPS latitude, longitude [deg] and altitude [m];
    GROUND_TRUTH velocity x, y, z [m/s] and chainage [km]; STROBE the sender's time [s].
    """

    sensor_type: SensorType
    seq_no: int
    doubles: tuple[float, ...] = ()
    ints: tuple[int, ...] = ()


@dataclass(frozen=True)
class OutputPacket:
    """One OUTPUT_PROTOCOL datagram: the fused chainage at an epoch."""

    seq_no: int
    epoch_s: float
    arc_length_km: float


@dataclass(frozen=True)
class Ack:
    """One ACK datagram: the last OUTPUT SEQ_NO the OBCU received."""

    seq_no: int


def _check_seq(seq_no: int) -> None:
    if not 0 <= seq_no < SEQ_MODULO:
        raise DatagramEncodeError(f"SEQ_NO {seq_no} outside 0..65535")


def encode_input(packet: InputPacket) -> bytes:
    _check_seq(packet.seq_no)
    expected = EXPECTED_COUNTS.get(packet.sensor_type)
    if expected is None:
        raise DatagramEncodeError(f"unknown sensor type {packet.sensor_type!r}")
    counts = (len(packet.ints), len(packet.doubles))
    if counts != expected:
        raise DatagramEncodeError(
            f"{packet.sensor_type.name} carries {expected} (ints, doubles), got {counts}"
        )
    if packet.ints and any(not _INT32_MIN <= value <= _INT32_MAX for value in packet.ints):
        raise DatagramEncodeError("an int value does not fit int32")
    return _MESSAGES[packet.sensor_type].pack(
        int(packet.sensor_type), packet.seq_no, *counts, *packet.ints, *packet.doubles
    )


def decode_input(data: bytes) -> InputPacket:
    """Decode an INPUT_PROTOCOL datagram; any malformation raises a typed error."""
    if len(data) < INPUT_HEADER_SIZE:
        raise TruncatedDatagramError(f"{len(data)} bytes, header needs {INPUT_HEADER_SIZE}")
    raw_type, seq_no, n_int, n_double = _HEADER.unpack_from(data)
    expected_length = INPUT_HEADER_SIZE + 4 * n_int + 8 * n_double
    if len(data) != expected_length:
        raise LengthMismatchError(
            f"{len(data)} bytes, header announces {expected_length} "
            f"({n_int} ints, {n_double} doubles)"
        )
    sensor_type = _SENSOR_TYPES.get(raw_type)
    if sensor_type is None:
        raise UnknownSensorTypeError(f"unknown SENSOR_TYPE {raw_type}")
    if (n_int, n_double) != EXPECTED_COUNTS[sensor_type]:
        raise CountMismatchError(
            f"{sensor_type.name} needs {EXPECTED_COUNTS[sensor_type]} (ints, doubles), "
            f"got {(n_int, n_double)}"
        )
    values = _MESSAGES[sensor_type].unpack(data)[_FIELDS_AFTER_HEADER:]
    # struct gives Python ints for "i" and floats for "d": the tuples are the packet's as they are.
    return InputPacket(sensor_type, seq_no, values[n_int:], values[:n_int])


def encode_output(packet: OutputPacket) -> bytes:
    _check_seq(packet.seq_no)
    if not (math.isfinite(packet.epoch_s) and math.isfinite(packet.arc_length_km)):
        raise DatagramEncodeError("EPOCH and FU_ARC_LEN must be finite")
    return _OUTPUT.pack(packet.seq_no, packet.epoch_s, packet.arc_length_km)


def decode_output(data: bytes) -> OutputPacket:
    if len(data) < OUTPUT_SIZE:
        raise TruncatedDatagramError(f"OUTPUT datagram of {len(data)} bytes, needs {OUTPUT_SIZE}")
    if len(data) != OUTPUT_SIZE:
        raise LengthMismatchError(f"OUTPUT datagram of {len(data)} bytes, needs {OUTPUT_SIZE}")
    seq_no, epoch_s, arc_length_km = _OUTPUT.unpack(data)
    return OutputPacket(seq_no=seq_no, epoch_s=epoch_s, arc_length_km=arc_length_km)


def encode_ack(ack: Ack) -> bytes:
    _check_seq(ack.seq_no)
    return _ACK.pack(ack.seq_no)


def decode_ack(data: bytes) -> Ack:
    if len(data) < ACK_SIZE:
        raise TruncatedDatagramError(f"ACK datagram of {len(data)} bytes, needs {ACK_SIZE}")
    if len(data) != ACK_SIZE:
        raise LengthMismatchError(f"ACK datagram of {len(data)} bytes, needs {ACK_SIZE}")
    return Ack(seq_no=_ACK.unpack(data)[0])
