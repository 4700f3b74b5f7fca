"""What the listener reports and counts, and what it accepts as a sensor's value.

- :class:`Health` and :class:`SfaStatus`: the fused estimate with its health, as of one epoch.
- :class:`ListenerCounters`: every datagram received is counted once, by outcome.
- :func:`plausible`: the range checks behind the ``invalid_value`` drop reason.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from enum import StrEnum

from protocol.udp import InputPacket, SensorType

__all__ = [
    "MAX_STROBE_BACKWARDS_S",
    "MAX_STROBE_GAP_S",
    "STROBE_PERIOD_S",
    "STROBE_TOLERANCE_S",
    "Health",
    "ListenerCounters",
    "SfaStatus",
    "plausible",
]

MAX_STROBE_GAP_S = 600.0
"""A STROBE further ahead of the last one than this [s] is implausible and dropped (a dead bus
of up to ten minutes is not)."""
MAX_STROBE_BACKWARDS_S = 1.0
"""A STROBE this far behind the last one [s] is dropped, unless a GROUND_TRUTH restarted the
run (a restarted sender sends GROUND_TRUTH first)."""
STROBE_PERIOD_S = 1.0
"""The sender's STROBE period [s] (CONTRACT.md §3: "sent once a second")."""
STROBE_TOLERANCE_S = 0.02
"""How far a STROBE may lie from a whole number of periods after the last one [s] and still be
on schedule (two IMU periods: the sequence-number bound on the epoch trails by as much)."""
MAX_ACCELERATION_MPS2 = 100.0
MAX_ANGULAR_RATE_RADPS = 35.0
MAX_SPEED_MPS = 150.0
MAX_SPEED_SIGMA_MPS = 50.0
MAX_ALTITUDE_M = 10_000.0


def plausible(packet: InputPacket, line_length_m: float) -> bool:
    """Whether a finite packet's values lie within what the sensors can report."""
    values = packet.doubles
    sensor_type = packet.sensor_type
    if sensor_type is SensorType.IMU:  # 100 Hz: loops, not generators
        for value in values[:3]:
            if not abs(value) <= MAX_ACCELERATION_MPS2:
                return False
        return all(abs(value) <= MAX_ANGULAR_RATE_RADPS for value in values[3:])
    if sensor_type is SensorType.ODOMETER:
        return abs(values[0]) <= MAX_SPEED_MPS and 0.0 <= values[1] <= MAX_SPEED_SIGMA_MPS
    if sensor_type is SensorType.GPS:
        return (
            abs(values[0]) <= 90.0 and abs(values[1]) <= 180.0 and abs(values[2]) <= MAX_ALTITUDE_M
        )
    if sensor_type is SensorType.GROUND_TRUTH:
        return all(abs(v) <= MAX_SPEED_MPS for v in values[:3]) and (
            0.0 <= values[3] * 1000.0 <= line_length_m
        )
    if sensor_type is SensorType.STROBE:
        return values[0] >= 0.0
    return True


class Health(StrEnum):
    OK = "ok"
    DEGRADED = "degraded"
    LOST = "lost"


@dataclass(frozen=True, slots=True)
class SfaStatus:
    """The fused estimate and the health behind it, as of one filter epoch."""

    epoch_s: float
    chainage_m: float
    """Unwrapped chainage [m] (keeps counting past the origin of a ring)."""
    speed_mps: float
    sigma_m: float
    health: Health
    imu_alive: bool
    odometer_alive: bool
    gps_alive: bool
    odometer_failed_at_s: float | None
    """Epoch [s] at which the current odometer failure was declared; None while it works."""


@dataclass
class ListenerCounters:
    received: int = 0
    processed: Counter[str] = field(default_factory=Counter)
    dropped: Counter[str] = field(default_factory=Counter)
    before_ground_truth: int = 0
    disabled: int = 0
    outputs_sent: int = 0
    acks_received: int = 0
    acks_malformed: int = 0

    def accounted(self, buffered: int) -> int:
        """Datagrams accounted for; equals ``received`` at every instant."""
        return (
            sum(self.processed.values())
            + sum(self.dropped.values())
            + self.before_ground_truth
            + self.disabled
            + buffered
        )
