"""Task B's speed, position, standstill and odometry efficiency from the tachometer frames
(seed 004, S6 and S6.2; DOMAIN.md §7.2).

Each frame of the odometry board carries a frame number and the cumulative pulses of two
channels on two axles. Over the interval since the previous frame:

- the speed is the channels' mean count times the metres a pulse, over the frames' nominal
  interval (80 ms), so it is an average over the last interval;
- the odometry is *not efficient* when a frame repeats the previous number (FROZEN), when the
  channels disagree by more than the tolerance (NOISY, a slipping or broken sensor), or when no
  frame came for longer than the timeout (SILENT); it is efficient again after
  ``recovery_frames`` good frames in a row. A frame whose number jumps by more than
  :data:`MAX_FRAME_GAP` (after an outage, or a corrupted counter) only serves as the reference
  for the next one;
- standstill is ``standstill_frames`` good frames without a pulse on either channel, and is
  never claimed while the odometry is not efficient.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from onboard.vc.config import TIME_TOLERANCE_S, VcConfig
from onboard.vc.hardware import FRAME_NUMBER_MODULO, TachometerFrame
from onboard.vc.ipc import Delivery

__all__ = ["MAX_FRAME_GAP", "OdometryEstimate", "TachometerOdometry"]

MAX_FRAME_GAP = 4
"""⚠ A frame number further than this from the previous one is implausible."""


@dataclass(frozen=True, slots=True, kw_only=True)
class OdometryEstimate:
    efficient: bool
    speed_mps: float | None
    """Mean speed over the last frame interval [m/s]; None while not efficient."""
    position_m: float | None
    """Distance run since power-up by channel A [m]; None before the first frame."""
    standstill: bool
    speed_updated_s: float | None
    """Arrival time of the frame the speed comes from [s]."""
    not_efficient_since_s: float | None
    """When the current inefficiency became evident (a bad frame, a timeout) [s]."""


class TachometerOdometry:
    """The estimator Task B runs on the frames it receives."""

    def __init__(self, config: VcConfig, *, start_s: float = 0.0) -> None:
        self.config = config
        self._metres_per_pulse = config.metres_per_pulse
        self._reference: TachometerFrame | None = None
        self._last_arrival_s = start_s
        self._good_frames = 0
        self._zero_frames = 0
        self._speed_mps = 0.0
        self._speed_updated_s: float | None = None
        self._position_m: float | None = None
        self._not_efficient_since_s: float | None = start_s
        self._estimate: OdometryEstimate | None = None
        self._estimated_from: tuple[object, ...] = ()

    def _bad(self, evidence_s: float) -> None:
        if self._not_efficient_since_s is None:
            self._not_efficient_since_s = evidence_s
        self._good_frames = 0
        self._zero_frames = 0

    def _frame(self, frame: TachometerFrame, arrived_s: float) -> None:
        reference = self._reference
        self._last_arrival_s = arrived_s
        if reference is None:
            self._reference = frame
            self._position_m = frame.pulses_a * self._metres_per_pulse
            return
        gap = (frame.frame_number - reference.frame_number) % FRAME_NUMBER_MODULO
        if gap == 0:
            self._bad(arrived_s)
            return
        self._reference = frame
        delta_a = frame.pulses_a - reference.pulses_a
        delta_b = frame.pulses_b - reference.pulses_b
        config = self.config
        tolerance = config.channel_tolerance_pulses + config.channel_tolerance_fraction * max(
            abs(delta_a), abs(delta_b)
        )
        if gap > MAX_FRAME_GAP or abs(delta_a - delta_b) > tolerance:
            self._bad(arrived_s)
            return
        self._good_frames += 1
        interval_s = gap * config.tachometer_period_s
        self._speed_mps = abs(delta_a + delta_b) / 2 * self._metres_per_pulse / interval_s
        self._speed_updated_s = arrived_s
        self._position_m = frame.pulses_a * self._metres_per_pulse
        self._zero_frames = self._zero_frames + gap if delta_a == 0 == delta_b else 0
        if self._good_frames >= config.recovery_frames:
            self._not_efficient_since_s = None

    def timeout_threshold_s(self) -> float:
        """:meth:`update` finds the board silent at any ``now_s`` above this [s]."""
        return self._last_arrival_s + self.config.tachometer_timeout_s + TIME_TOLERANCE_S

    def state_key(self) -> tuple[object, ...]:
        """The estimator's whole state, for comparing two instants."""
        return (
            self._reference,
            self._last_arrival_s,
            self._good_frames,
            self._zero_frames,
            self._speed_mps,
            self._speed_updated_s,
            self._position_m,
            self._not_efficient_since_s,
        )

    def update(self, now_s: float, frames: Sequence[Delivery[TachometerFrame]]) -> OdometryEstimate:
        """Take the frames arrived since the last call; return the estimate at ``now_s``."""
        for delivery in frames:
            self._frame(delivery.message, delivery.arrived_s)
        deadline_s = self._last_arrival_s + self.config.tachometer_timeout_s
        if now_s > deadline_s + TIME_TOLERANCE_S:
            self._bad(deadline_s)
        efficient = self._not_efficient_since_s is None
        key = (
            efficient,
            self._speed_mps,
            self._position_m,
            self._zero_frames,
            self._speed_updated_s,
            self._not_efficient_since_s,
        )
        if key == self._estimated_from and self._estimate is not None:
            # Task B asks every 2 ms, a frame comes every 80 ms: the same state, the same
            # (frozen) estimate.
            return self._estimate
        self._estimated_from = key
        self._estimate = OdometryEstimate(
            efficient=efficient,
            speed_mps=self._speed_mps if efficient else None,
            position_m=self._position_m,
            standstill=efficient and self._zero_frames >= self.config.standstill_frames,
            speed_updated_s=self._speed_updated_s,
            not_efficient_since_s=self._not_efficient_since_s,
        )
        return self._estimate
