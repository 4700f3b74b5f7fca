"""The Vital Control's parameters (seeds 001, 004; DOMAIN.md §7.2), in one frozen object.

Values from the seeds are marked with their source; every other value is an assumption (⚠),
kept configurable and listed in docs/vc.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from onboard.vc._exceptions import VcInputError
from protocol.units import MPS_PER_KMH

__all__ = ["TIME_TOLERANCE_S", "VcConfig"]

TIME_TOLERANCE_S = 1e-6
"""Two simulated instants closer than this are the same instant (float sums of periods)."""


@dataclass(frozen=True, kw_only=True)
class VcConfig:
    """Periods, windows, timeouts and thresholds of the three tasks.

    Durations in s, speeds in m/s, lengths in m.
    """

    task_a_period_s: float = 0.040
    """Task A, the request composer: 40 ms (seed 004, Table 5)."""
    task_b_period_s: float = 0.002
    """Task B, the supervisor: 2 ms, highest priority (seed 004)."""
    task_c_period_s: float = 0.002
    """Task C, the actuator: 2 ms, after B (seed 004)."""
    exchange_window_s: float = 0.044
    """A request's answer must be read within 40 ms + 4 ms of its sending (seed 004)."""
    vigilance_period_s: float = 5.0
    """⚠ How often the operator's vigilance is asked for (measured from the previous request)."""
    vigilance_timeout_s: float = 2.0
    """⚠ How long the operator has to confirm vigilance before EB and System Decay."""
    speed_limit_etcs_isolated_mps: float = 30.0 * MPS_PER_KMH
    """With ETCS isolated the VC brakes above 30 km/h (seed 004, S6.1)."""
    tachometer_period_s: float = 0.080
    """The odometry board sends a frame every 80 ms (seed 004)."""
    tachometer_timeout_s: float = 0.096
    """⚠ No frame for longer than this: the odometry is not efficient (1.2 periods: 20 % of
    jitter allowed on the board's 80 ms)."""
    wheel_diameter_m: float = 0.84
    """⚠ Wheel diameter of the tachometer axles."""
    pulses_per_revolution: int = 256
    """⚠ Tachometer pulses per wheel revolution (about 1 cm a pulse)."""
    channel_tolerance_pulses: int = 3
    """⚠ The two tachometer channels may differ by this many pulses a frame ..."""
    channel_tolerance_fraction: float = 0.05
    """⚠ ... plus this fraction of the larger count, before the odometry is not efficient."""
    standstill_frames: int = 3
    """⚠ Frames without a pulse on either channel before standstill (240 ms)."""
    recovery_frames: int = 3
    """⚠ Consecutive good frames before the odometry is efficient again."""
    relay_verification_timeout_s: float = 0.100
    """⚠ The radio relay must read back its commanded state within this time."""
    rearm_timeout_s: float = 2.0
    """⚠ After the rearm command the EB input must read "released" within this time."""
    sequence_modulo: int = 256
    """⚠ Sequence numbers are one byte and wrap."""
    fused_speed_supervision: bool = False
    """Beyond the seeds (issue 7, item 5): with ETCS isolated, supervise the speed limit on the
    larger of the tachometer speed (every 80 ms) and the sensor-fusion speed (every tick it
    comes); never less restrictive than the tachometer alone, and up to 120 ms sooner."""
    fused_speed_timeout_s: float = 0.020
    """⚠ A fused speed older than this is ignored (the tachometer alone supervises)."""
    fused_speed_margin_mps: float = 0.10
    """⚠ The fused speed is supervised with this margin added: about two standard deviations
    of its error (0.2 km/h RMS), as ETCS adds its speed inaccuracy [m/s]."""

    def __post_init__(self) -> None:
        for item in fields(self):
            if item.name == "fused_speed_supervision":
                continue
            value = getattr(self, item.name)
            if not (math.isfinite(value) and value > 0):
                raise VcInputError(f"{item.name} must be positive and finite, got {value}")
        for name in ("pulses_per_revolution", "standstill_frames", "recovery_frames"):
            if not isinstance(getattr(self, name), int):
                raise VcInputError(f"{name} must be an integer")
        if self.channel_tolerance_fraction >= 1.0:
            raise VcInputError("channel_tolerance_fraction must be below 1")
        if self.exchange_window_s < self.task_a_period_s:
            raise VcInputError("the exchange window cannot be shorter than Task A's period")
        if self.sequence_modulo < 4:
            raise VcInputError("sequence numbers need at least two bits")

    @property
    def metres_per_pulse(self) -> float:
        """Wheel circumference over the pulses a revolution [m]."""
        return math.pi * self.wheel_diameter_m / self.pulses_per_revolution
