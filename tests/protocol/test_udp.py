"""UDP codecs of CONTRACT.md §3: exact layouts, round trips, and typed errors for bad input."""

from __future__ import annotations

import contextlib
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from protocol import (
    CountMismatchError,
    DatagramEncodeError,
    LengthMismatchError,
    MalformedDatagramError,
    TruncatedDatagramError,
    UnknownSensorTypeError,
)
from protocol.udp import (
    EXPECTED_COUNTS,
    Ack,
    InputPacket,
    OutputPacket,
    SensorType,
    decode_ack,
    decode_input,
    decode_output,
    encode_ack,
    encode_input,
    encode_output,
)

seq_numbers = st.integers(min_value=0, max_value=65535)
doubles = st.floats(allow_nan=False, width=64)


@st.composite
def input_packets(draw: st.DrawFn) -> InputPacket:
    sensor = draw(st.sampled_from(list(SensorType)))
    n_int, n_double = EXPECTED_COUNTS[sensor]
    return InputPacket(
        sensor_type=sensor,
        seq_no=draw(seq_numbers),
        ints=tuple(
            draw(st.lists(st.integers(-(2**31), 2**31 - 1), min_size=n_int, max_size=n_int))
        ),
        doubles=tuple(draw(st.lists(doubles, min_size=n_double, max_size=n_double))),
    )


@given(input_packets())
def test_input_round_trip(packet: InputPacket) -> None:
    data = encode_input(packet)
    assert len(data) == 5 + 4 * len(packet.ints) + 8 * len(packet.doubles)
    assert decode_input(data) == packet


@given(
    seq_numbers,
    st.floats(allow_nan=False, allow_infinity=False),
    st.floats(allow_nan=False, allow_infinity=False),
)
def test_output_round_trip(seq_no: int, epoch: float, arc: float) -> None:
    packet = OutputPacket(seq_no=seq_no, epoch_s=epoch, arc_length_km=arc)
    data = encode_output(packet)
    assert len(data) == 18
    assert decode_output(data) == packet


@given(seq_numbers)
def test_ack_round_trip(seq_no: int) -> None:
    data = encode_ack(Ack(seq_no))
    assert len(data) == 2
    assert decode_ack(data) == Ack(seq_no)


def test_input_layout_is_little_endian_as_in_the_contract() -> None:
    packet = InputPacket(SensorType.ODOMETER, seq_no=0x0102, doubles=(1.5, 0.25))
    expected = bytes([2, 0x02, 0x01, 0, 2]) + struct.pack("<dd", 1.5, 0.25)
    assert encode_input(packet) == expected


def test_output_and_ack_layouts() -> None:
    assert encode_output(OutputPacket(7, 2.0, 3.5)) == struct.pack("<Hdd", 7, 2.0, 3.5)
    assert encode_ack(Ack(0xBEEF)) == b"\xef\xbe"


def test_imu_at_rest_example() -> None:
    data = struct.pack("<BHBB6d", 1, 65535, 0, 6, 0.0, 0.0, -9.81, 0.0, 0.0, 0.0)
    packet = decode_input(data)
    assert packet.sensor_type is SensorType.IMU
    assert packet.seq_no == 65535
    assert packet.doubles[2] == pytest.approx(-9.81, abs=1e-12)


@pytest.mark.parametrize(
    ("data", "error"),
    [
        (b"", TruncatedDatagramError),
        (b"\x01\x00\x00\x00", TruncatedDatagramError),
        # short: the header announces 6 doubles, 5 follow
        (struct.pack("<BHBB5d", 1, 0, 0, 6, *[0.0] * 5), LengthMismatchError),
        # long: one byte too many
        (struct.pack("<BHBB2d", 2, 0, 0, 2, 1.0, 0.1) + b"\x00", LengthMismatchError),
        # unknown type with a consistent length
        (struct.pack("<BHBBd", 4, 0, 0, 1, 1.0), UnknownSensorTypeError),
        (struct.pack("<BHBB", 0, 0, 0, 0), UnknownSensorTypeError),
        # count mismatch: GPS with 2 doubles, STOP with an int
        (struct.pack("<BHBB2d", 3, 0, 0, 2, 44.5, 11.3), CountMismatchError),
        (struct.pack("<BHBBi", 10, 0, 1, 0, 5), CountMismatchError),
    ],
    ids=[
        "empty",
        "header-cut",
        "short",
        "long",
        "unknown-type",
        "type-zero",
        "gps-count",
        "stop-int",
    ],
)
def test_malformed_input_raises_the_typed_error(data: bytes, error: type[Exception]) -> None:
    with pytest.raises(error) as caught:
        decode_input(data)
    assert isinstance(caught.value, MalformedDatagramError)
    assert isinstance(caught.value, ValueError)


@given(st.binary(max_size=128))
def test_any_bytes_decode_or_raise_only_the_typed_error(data: bytes) -> None:
    for decode in (decode_input, decode_output, decode_ack):
        with contextlib.suppress(MalformedDatagramError):
            decode(data)


@pytest.mark.parametrize("data", [b"", b"\x01", b"\x01\x02\x03"])
def test_malformed_ack(data: bytes) -> None:
    with pytest.raises(MalformedDatagramError):
        decode_ack(data)


@pytest.mark.parametrize("size", [0, 17, 19])
def test_malformed_output(size: int) -> None:
    with pytest.raises(MalformedDatagramError):
        decode_output(bytes(size))


def test_encoding_refuses_what_the_wire_cannot_carry() -> None:
    with pytest.raises(DatagramEncodeError):
        encode_input(InputPacket(SensorType.STOP, seq_no=65536))
    with pytest.raises(DatagramEncodeError):
        encode_input(InputPacket(SensorType.GPS, seq_no=0, doubles=(1.0,)))
    with pytest.raises(DatagramEncodeError):
        encode_output(OutputPacket(0, float("nan"), 0.0))
    with pytest.raises(DatagramEncodeError):
        encode_ack(Ack(-1))
