"""The ETCS odometer on the axle-end wheel sensors (SUBSET-026 §3.6; SUBSET-041 §5.3; DOMAIN.md §6).

ETCS sees the train's motion through two pulse generators, one on each axle of the bogie. The
plant gives each axle's travel as its calibrated wheel converts the rotation
(:class:`onboard.plant.readings.WheelReading`, every 10 ms); this module turns it into pulses
and estimates from them, once per reading:

- the pulse counts: ``floor(travel · pulses per metre)`` on each channel, counted from the
  first reading (the onboard's start position);
- each axle's speed: the pulses of the last ``speed_window_s`` over that time (a 200-pulse
  generator on a 0.92 m wheel gives 69.2 pulses/m, so a 0.2 s window resolves 0.072 m/s,
  well inside V_ura's 0.56 m/s);
- each axle's acceleration: the change of that speed over the same window;
- wheel slip or slide (:meth:`OdometerParameters.slip_criterion`): the two axles disagree by
  more than ``axle_difference_mps`` + ``axle_difference_ratio`` of the speed (more than two
  wheels' diameter tolerance could explain), or an axle accelerates or decelerates faster
  than ``max_wheel_acceleration_mps2`` / ``max_wheel_deceleration_mps2`` (more than the
  vehicle's traction, brakes and steepest gradient allow: only a wheel that has lost
  adhesion does so). It lasts until no criterion has held for ``slip_recovery_s``;
- distance and speed. Without slip: the mean of the two axles. During slip or slide the wheels
  no longer measure the ground, so the odometer bounds the ground speed instead and counts the
  distance at the estimate, see below;
- the acceleration A_est: the change of the speed estimate over ``acceleration_window_s``.

Slip and slide. The odometer keeps an envelope [low, high] of the ground speed, started at
slip onset around the last estimate (widened by everything that estimate may be wrong by) and
opened at the vehicle's own limits each sample (``max_vehicle_acceleration_mps2`` up,
``max_vehicle_deceleration_mps2`` down: adhesion lost or not, the train cannot change speed
faster). Whether the wheels were motoring or braking comes from A_est at the onset (at least
``motoring_evidence_mps2``: motoring; at most minus ``braking_evidence_mps2``: braking; the
slip itself only pulls A_est further the same way), not from which axle departs from the
estimate, which a slow slip of one axle leaves symmetric. The wheels then close one side: a
slipping wheel (motoring) turns at least as fast as the ground, so the lower axle bounds the
ground speed from above and gives the estimate; a sliding wheel (braking) turns at most as
fast, so the higher axle bounds it from below and gives the estimate. Unknown, no wheel bounds
the ground and the estimate follows the axle nearer the speed A_est predicts. The estimate is
kept inside the envelope; the distance counts at it, and the odometer adds to its slip/slide
allowances what the envelope leaves open: (high − estimate)·dt ahead and (estimate − low)·dt
behind. Those allowances only grow; the confidence interval (:mod:`onboard.etcs.odometry`)
takes what they added since the last balise group, so the interval grows during slip and slide
at the rate of the envelope's width (tens of per cent of the distance run, against 3 % when the
wheels roll) and is reset at the next group. A wheel locked (or spinning) at a steady speed
meets neither criterion, so the slip or slide also lasts while a wheel reads outside the
envelope: a locked wheel stays covered until the envelope admits standstill.

⚠ Wheels alone cannot see a slip or slide common to both axles that neither criterion shows
(both creeping steadily at the same few per cent, or spinning up together slower than
``max_wheel_acceleration_mps2``): it reads beyond the creep allowance unseen. Nor can they tell
a wheel locked longer than the envelope needs to reach 0 from a stopped train. A radar or an
accelerometer would.

Accuracy law (:meth:`OdometerParameters.accuracy`), with the rolling wheels::

    error = fixed_error_m + 2 pulses + (diameter_tolerance + creep_allowance)·s
          = 2.03 m + 3 %·s                                    (the URV defaults)

- 2 %: the calibrated wheel diameter may be off by ±2 % (wear between calibrations): both
  axles' travel, and their mean, read up to 2 % long or short;
- 1 %: the creep of wheels transmitting traction or braking force without slipping (a few
  tenths of a per cent under Polach's law at the URV's loads), with margin;
- 2 pulses (0.03 m): each channel's count is floored at both ends of s;
- 2 m: slip or slide before it is detected (a slip that stays under both criteria runs up to
  about half a metre before the axles disagree enough), the linear interpolation of the
  odometer at a balise detection's time (millimetres) and margin.

It keeps within SUBSET-041's requirement, 5 m + 5 %·s (DOMAIN.md §6;
:data:`onboard.etcs.odometry.SUBSET_041_ACCURACY`), which :class:`OdometerParameters` checks.
A group read by the balise reader adds ``balise_location_error_m`` to its Q_LOCACC (the reader
locates a group's centre within σ ≈ 0.3–0.5 m; 1.5 m is three σ of the worst).

⚠ The pulse generator (200 pulses per revolution), the wheel (0.92 m, the bogie model's), the
thresholds and the vehicle limits are assumptions kept consistent with the plant
(``onboard/plant/point_mass.py``: 30 kN traction and 15 kN brake on 15 t, 8 % rotating mass, so
1.85 m/s² and 0.93 m/s² on level track; ±35 ‰ adds 0.34 m/s²).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable
from dataclasses import dataclass, fields
from enum import StrEnum
from typing import NamedTuple

from onboard.etcs._exceptions import EtcsInputError, TrainDataError
from onboard.etcs.odometry import SUBSET_041_ACCURACY, OdometryAccuracy
from onboard.plant.readings import WheelReading

__all__ = [
    "URV_ODOMETER",
    "Odometer",
    "OdometerOutput",
    "OdometerParameters",
    "OdometerPosition",
    "WheelAdhesion",
]


@dataclass(frozen=True, kw_only=True)
class OdometerParameters:
    """The odometer's sensors, thresholds and error budget (see the module's docstring)."""

    wheel_diameter_m: float = 0.92
    """The calibrated wheel diameter [m] the pulses are converted with."""
    pulses_per_revolution: int = 200
    diameter_tolerance: float = 0.02
    """How far the real wheel diameter may be from the calibrated one (a fraction)."""
    creep_allowance: float = 0.01
    """Creep of wheels that transmit force without slipping (a fraction of the distance)."""
    fixed_error_m: float = 2.0
    """The law's fixed part besides quantisation [m]: undetected slip onsets and margin."""
    speed_window_s: float = 0.2
    """Time [s] over which pulses are counted into a speed, and speeds into a wheel's
    acceleration."""
    acceleration_window_s: float = 0.5
    """Time [s] over which the speed estimate's change gives A_est."""
    axle_difference_mps: float = 0.5
    axle_difference_ratio: float = 0.045
    """Axles disagreeing by more than ``axle_difference_mps`` + this ratio of the speed slip
    (two diameter tolerances, 4 %, and margin)."""
    max_wheel_acceleration_mps2: float = 3.0
    max_wheel_deceleration_mps2: float = 3.0
    """A wheel changing speed faster than these [m/s²] slips or slides."""
    max_vehicle_acceleration_mps2: float = 2.5
    """The fastest the vehicle itself can speed up [m/s²]: traction plus the steepest downhill."""
    max_vehicle_deceleration_mps2: float = 1.5
    """The fastest it can slow down [m/s²]: EB, resistance and the steepest uphill."""
    motoring_evidence_mps2: float = 0.3
    """A_est at a slip's onset at or above this [m/s²]: the wheels were motoring (slip)."""
    braking_evidence_mps2: float = 0.6
    """A_est at or below minus this [m/s²]: they were braking (slide); between, unknown."""
    slip_recovery_s: float = 0.5
    """Slip or slide ends once no criterion has held for this long [s]."""
    balise_location_error_m: float = 1.5
    """The balise reader's location error [m], added to a group's Q_LOCACC."""
    history_s: float = 2.0
    """How long [s] the odometer keeps its samples, to place a balise detection in time."""

    def __post_init__(self) -> None:
        for field in fields(self):
            value = getattr(self, field.name)
            if not (math.isfinite(value) and value >= 0):
                raise TrainDataError(f"odometer {field.name} must be finite and ≥ 0")
        if self.wheel_diameter_m <= 0.0 or self.pulses_per_revolution < 1:
            raise TrainDataError("the odometer needs a wheel diameter > 0 and ≥ 1 pulse per turn")
        if not (self.speed_window_s > 0.0 and self.acceleration_window_s > 0.0):
            raise TrainDataError("the odometer's windows must be > 0 s")
        if self.history_s < max(self.speed_window_s, self.acceleration_window_s):
            raise TrainDataError("the odometer's history must cover its windows")
        if not (self.diameter_tolerance < 0.5 and self.max_vehicle_deceleration_mps2 > 0.0):
            raise TrainDataError("diameter tolerance < 50 % and a vehicle deceleration > 0")
        if not self.accuracy().within(SUBSET_041_ACCURACY):
            raise TrainDataError("the odometer's accuracy law exceeds SUBSET-041's 5 m + 5 %")

    @property
    def pulses_per_metre(self) -> float:
        """Pulses [1/m] one channel gives per metre of its wheel's travel."""
        return self.pulses_per_revolution / (math.pi * self.wheel_diameter_m)

    @property
    def pulse_m(self) -> float:
        """The length [m] of one pulse: the quantum of the distance."""
        return 1.0 / self.pulses_per_metre

    @property
    def speed_resolution_mps(self) -> float:
        """One pulse per speed window [m/s]: the quantum of a windowed speed."""
        return self.pulse_m / self.speed_window_s

    def accuracy(self) -> OdometryAccuracy:
        """The odometer's error law while the wheels roll (see the module's docstring)."""
        return OdometryAccuracy(
            fixed_error_m=self.fixed_error_m + 2.0 * self.pulse_m,
            proportional_error=self.diameter_tolerance + self.creep_allowance,
        )

    def axle_difference_limit_mps(self, speed_mps: float) -> float:
        """The axles' disagreement [m/s] beyond which a wheel slips or slides at this speed."""
        return self.axle_difference_mps + self.axle_difference_ratio * abs(speed_mps)

    def slip_criterion(
        self,
        front_mps: float,
        rear_mps: float,
        front_mps2: float,
        rear_mps2: float,
    ) -> bool:
        """Whether the axles' speeds [m/s] and accelerations [m/s²] show slip or slide."""
        fastest_mps = max(abs(front_mps), abs(rear_mps))
        return (
            abs(front_mps - rear_mps) > self.axle_difference_limit_mps(fastest_mps)
            or max(front_mps2, rear_mps2) > self.max_wheel_acceleration_mps2
            or min(front_mps2, rear_mps2) < -self.max_wheel_deceleration_mps2
        )


URV_ODOMETER = OdometerParameters()
"""The URV's odometer: 200 pulses per turn of its 0.92 m wheels (assumed, see the module)."""


class WheelAdhesion(StrEnum):
    """What the odometer sees of the wheels' grip on the rail."""

    ROLLING = "rolling"
    SLIP = "slip"
    """A wheel turns faster than the ground passes (motoring beyond adhesion)."""
    SLIDE = "slide"
    """A wheel turns slower than the ground passes (braking beyond adhesion)."""


@dataclass(frozen=True, kw_only=True)
class OdometerPosition:
    """The odometer at an instant: distance counted and cumulative slip/slide allowances [m]."""

    time_s: float
    distance_m: float
    slip_slide_over_m: float
    """Allowance ahead [m]: the ground may have run this much further than counted."""
    slip_slide_under_m: float
    """Allowance behind [m]: the ground may have run this much less than counted."""


@dataclass(frozen=True, kw_only=True)
class OdometerOutput:
    """The odometer after its last wheel reading."""

    time_s: float
    distance_m: float
    """The distance [m] counted since the first reading."""
    speed_mps: float
    """The estimated speed [m/s], ≥ 0."""
    acceleration_mps2: float
    """The estimated acceleration [m/s²], A_est."""
    front_axle_speed_mps: float
    rear_axle_speed_mps: float
    pulses_front: int
    pulses_rear: int
    adhesion: WheelAdhesion
    slip_slide_over_m: float
    """Cumulative allowance ahead [m] from slip and slide since the first reading."""
    slip_slide_under_m: float
    """Cumulative allowance behind [m] from slip and slide since the first reading."""

    @property
    def slip(self) -> bool:
        """Wheel slip detected (motoring)."""
        return self.adhesion is WheelAdhesion.SLIP

    @property
    def slide(self) -> bool:
        """Wheel slide detected (braking)."""
        return self.adhesion is WheelAdhesion.SLIDE


class _Sample(NamedTuple):
    """One counted reading (a tuple: a thousand are made per simulated second)."""

    time_s: float
    pulses_front: int
    pulses_rear: int
    front_mps: float
    rear_mps: float
    distance_m: float
    speed_mps: float
    over_m: float
    under_m: float
    full_window: bool
    """Whether the axle speeds span a whole speed window."""


class Odometer:
    """Pulse counting, speed, acceleration, slip and slide from the wheel readings.

    Parameters
    ----------
    parameters : OdometerParameters
        The sensors and thresholds; the URV's by default.
    start_s : float
        The time [s] of the odometer's zero until the first reading comes.

    The first reading fixes the zero: distances count from the travel it gives.
    """

    def __init__(
        self, parameters: OdometerParameters = URV_ODOMETER, *, start_s: float = 0.0
    ) -> None:
        if not math.isfinite(start_s):
            raise EtcsInputError("the odometer's start time must be finite")
        self.parameters = parameters
        self._ppm = parameters.pulses_per_metre
        self._zero: tuple[int, int] | None = None
        self._samples: list[_Sample] = []
        self._times: list[float] = []
        self._adhesion = WheelAdhesion.ROLLING
        self._regime = WheelAdhesion.ROLLING
        """SLIP or SLIDE when A_est at the onset said motoring or braking; ROLLING: unknown."""
        self._onset_acceleration_mps2 = 0.0
        self._last_criterion_s = -math.inf
        self._low_mps = self._high_mps = 0.0
        self._output: OdometerOutput | None = OdometerOutput(
            time_s=start_s,
            distance_m=0.0,
            speed_mps=0.0,
            acceleration_mps2=0.0,
            front_axle_speed_mps=0.0,
            rear_axle_speed_mps=0.0,
            pulses_front=0,
            pulses_rear=0,
            adhesion=WheelAdhesion.ROLLING,
            slip_slide_over_m=0.0,
            slip_slide_under_m=0.0,
        )
        self._last: tuple[_Sample, float, WheelAdhesion] | None = None
        """The newest sample, its acceleration [m/s²] and the adhesion then: the output is
        made of them when read, not at each reading counted."""

    @property
    def output(self) -> OdometerOutput:
        """The estimate at the newest reading counted."""
        output = self._output
        if output is None:
            assert self._last is not None
            sample, acceleration_mps2, adhesion = self._last
            output = self._output = OdometerOutput(
                time_s=sample.time_s,
                distance_m=sample.distance_m,
                speed_mps=max(sample.speed_mps, 0.0),
                acceleration_mps2=acceleration_mps2,
                front_axle_speed_mps=sample.front_mps,
                rear_axle_speed_mps=sample.rear_mps,
                pulses_front=sample.pulses_front,
                pulses_rear=sample.pulses_rear,
                adhesion=adhesion,
                slip_slide_over_m=sample.over_m,
                slip_slide_under_m=sample.under_m,
            )
        return output

    def update(self, readings: Iterable[WheelReading]) -> OdometerOutput:
        """Count the readings since the last update (in time order) and estimate.

        A reading at the time of the last one counted is skipped; an earlier one is an error.
        The readings' speeds are not used: the odometer measures from its own pulses.
        """
        for reading in readings:
            self._count(reading)
        return self.output

    def position_at(self, time_s: float) -> OdometerPosition:
        """The odometer at ``time_s`` [s], interpolated between its samples.

        After the last sample it runs on at the estimated speed; before the oldest one kept
        (``history_s``) it is that sample's.
        """
        if not math.isfinite(time_s):
            raise EtcsInputError(f"time {time_s} s is not finite")
        out = self.output
        if not self._samples or time_s >= out.time_s:
            ahead_s = max(time_s - out.time_s, 0.0) if self._samples else 0.0
            return OdometerPosition(
                time_s=time_s,
                distance_m=out.distance_m + out.speed_mps * ahead_s,
                slip_slide_over_m=out.slip_slide_over_m,
                slip_slide_under_m=out.slip_slide_under_m,
            )
        index = bisect.bisect_right(self._times, time_s)
        if index == 0:
            first = self._samples[0]
            return OdometerPosition(
                time_s=time_s,
                distance_m=first.distance_m,
                slip_slide_over_m=first.over_m,
                slip_slide_under_m=first.under_m,
            )
        before, after = self._samples[index - 1], self._samples[index]
        share = (time_s - before.time_s) / (after.time_s - before.time_s)

        def between(a: float, b: float) -> float:
            return a + share * (b - a)

        return OdometerPosition(
            time_s=time_s,
            distance_m=between(before.distance_m, after.distance_m),
            slip_slide_over_m=between(before.over_m, after.over_m),
            slip_slide_under_m=between(before.under_m, after.under_m),
        )

    # -- internals -----------------------------------------------------------------------------

    def _base(self, time_s: float) -> _Sample:
        """The newest sample at or before ``time_s``, else the oldest kept."""
        index = bisect.bisect_right(self._times, time_s)
        return self._samples[max(index - 1, 0)]

    def _count(self, reading: WheelReading) -> None:
        time_s = reading.time_s
        if not all(
            math.isfinite(value)
            for value in (time_s, reading.travel_front_m, reading.travel_rear_m)
        ):
            raise EtcsInputError("a wheel reading's time and travels must be finite")
        pulses = (
            math.floor(reading.travel_front_m * self._ppm),
            math.floor(reading.travel_rear_m * self._ppm),
        )
        if self._zero is None:
            self._zero = pulses
            self._append(_Sample(time_s, 0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False), 0.0)
            return
        previous = self._samples[-1]
        if time_s <= previous.time_s:
            if time_s == previous.time_s:
                return
            raise EtcsInputError(f"wheel reading at {time_s} s before {previous.time_s} s")
        front, rear = pulses[0] - self._zero[0], pulses[1] - self._zero[1]
        p = self.parameters
        base = self._base(time_s - p.speed_window_s)
        window_s = time_s - base.time_s
        front_mps = (front - base.pulses_front) / self._ppm / window_s
        rear_mps = (rear - base.pulses_rear) / self._ppm / window_s
        # Until the history spans whole windows the speeds are too coarse to judge.
        full_window = window_s >= p.speed_window_s
        criterion = False
        if full_window:
            front_mps2 = (front_mps - base.front_mps) / window_s if base.full_window else 0.0
            rear_mps2 = (rear_mps - base.rear_mps) / window_s if base.full_window else 0.0
            criterion = p.slip_criterion(front_mps, rear_mps, front_mps2, rear_mps2)
        # A wheel locked (or spinning) at a steady speed meets neither criterion; it still
        # slides (slips) while it reads slower (faster) than the ground can possibly run.
        if criterion or not self._envelope_admits(front_mps, rear_mps):
            self._last_criterion_s = time_s
        dt_s = time_s - previous.time_s
        if time_s - self._last_criterion_s < p.slip_recovery_s:
            speed_mps, over_m, under_m = self._bounded_speed(previous, front_mps, rear_mps, dt_s)
            distance_m = previous.distance_m + 0.5 * (previous.speed_mps + speed_mps) * dt_s
        else:
            self._adhesion = WheelAdhesion.ROLLING
            speed_mps, over_m, under_m = 0.5 * (front_mps + rear_mps), 0.0, 0.0
            counted = front - previous.pulses_front + rear - previous.pulses_rear
            distance_m = previous.distance_m + counted / (2.0 * self._ppm)
        sample = _Sample(
            time_s,
            front,
            rear,
            front_mps,
            rear_mps,
            distance_m,
            speed_mps,
            previous.over_m + over_m,
            previous.under_m + under_m,
            full_window,
        )
        accel_base = self._base(time_s - p.acceleration_window_s)
        self._append(sample, (speed_mps - accel_base.speed_mps) / (time_s - accel_base.time_s))

    def _wheel_bounds_mps(self, wheel_mps: float) -> tuple[float, float]:
        """The ground speeds [m/s] a rolling wheel whose windowed speed reads ``wheel_mps``
        allows: its diameter tolerance, one speed quantum and the vehicle's own change of
        speed over the window."""
        p = self.parameters
        lag_mps = p.speed_resolution_mps + p.speed_window_s * max(
            p.max_vehicle_acceleration_mps2, p.max_vehicle_deceleration_mps2
        )
        return (
            (wheel_mps - lag_mps) / (1.0 + p.diameter_tolerance),
            (wheel_mps + lag_mps) / (1.0 - p.diameter_tolerance),
        )

    def _envelope_admits(self, front_mps: float, rear_mps: float) -> bool:
        """Whether both axles could be rolling, given the ground speed envelope of the slip
        or slide under way (always true when none is)."""
        if self._adhesion is WheelAdhesion.ROLLING:
            return True
        for wheel_mps in (front_mps, rear_mps):
            low_mps, high_mps = self._wheel_bounds_mps(wheel_mps)
            if high_mps < self._low_mps or low_mps > self._high_mps:
                return False
        return True

    def _bounded_speed(
        self, previous: _Sample, front_mps: float, rear_mps: float, dt_s: float
    ) -> tuple[float, float, float]:
        """(estimate [m/s], allowance ahead [m], allowance behind [m]) of one slip sample."""
        p = self.parameters
        if self._adhesion is WheelAdhesion.ROLLING:
            self._start_envelope(previous.speed_mps)
        self._high_mps += p.max_vehicle_acceleration_mps2 * dt_s
        self._low_mps = max(self._low_mps - p.max_vehicle_deceleration_mps2 * dt_s, 0.0)
        fast_mps, slow_mps = max(front_mps, rear_mps), min(front_mps, rear_mps)
        if self._regime is WheelAdhesion.SLIP:
            chosen_mps = slow_mps
            bound_mps = self._wheel_bounds_mps(slow_mps)[1]
            self._high_mps = max(min(self._high_mps, bound_mps), self._low_mps)
        elif self._regime is WheelAdhesion.SLIDE:
            chosen_mps = fast_mps
            bound_mps = self._wheel_bounds_mps(fast_mps)[0]
            self._low_mps = min(max(self._low_mps, bound_mps), self._high_mps)
        else:
            # Motoring or braking unknown: no wheel bounds the ground; follow the axle nearer
            # the speed the vehicle's acceleration at the onset predicts.
            predicted_mps = previous.speed_mps + self._onset_acceleration_mps2 * dt_s
            above = fast_mps - predicted_mps >= predicted_mps - slow_mps
            chosen_mps = slow_mps if above else fast_mps
            self._adhesion = WheelAdhesion.SLIP if above else WheelAdhesion.SLIDE
        speed_mps = min(max(chosen_mps, self._low_mps), self._high_mps)
        return (
            speed_mps,
            (self._high_mps - speed_mps) * dt_s,
            (speed_mps - self._low_mps) * dt_s,
        )

    def _start_envelope(self, speed_mps: float) -> None:
        """A slip or slide begins: the envelope around the last estimate [m/s] and the regime
        from A_est, which the slip itself only pulls further the same way."""
        p = self.parameters
        # The last estimate came from the mean of the axles, which an undetected slip may have
        # pulled by up to half the disagreement threshold.
        low_mps, high_mps = self._wheel_bounds_mps(speed_mps)
        half_mps = p.axle_difference_limit_mps(speed_mps) / 2.0
        self._low_mps, self._high_mps = max(low_mps - half_mps, 0.0), high_mps + half_mps
        acceleration_mps2 = 0.0 if self._last is None else self._last[1]
        self._onset_acceleration_mps2 = acceleration_mps2
        if acceleration_mps2 >= p.motoring_evidence_mps2:
            self._regime = WheelAdhesion.SLIP
        elif acceleration_mps2 <= -p.braking_evidence_mps2:
            self._regime = WheelAdhesion.SLIDE
        else:
            self._regime = WheelAdhesion.ROLLING
        self._adhesion = self._regime

    def _append(self, sample: _Sample, acceleration_mps2: float) -> None:
        self._samples.append(sample)
        self._times.append(sample.time_s)
        keep_from = bisect.bisect_right(self._times, sample.time_s - self.parameters.history_s)
        if keep_from > len(self._times) // 2:
            del self._samples[: keep_from - 1]
            del self._times[: keep_from - 1]
        self._last = (sample, acceleration_mps2, self._adhesion)
        self._output = None
