"""Odometry confidence interval: where the front end may be (SUBSET-026 §3.6.4; DOMAIN.md §6).

The estimated front end is the location of the last relevant balise group (LRBG) plus the
odometer's travel since the group was read. Around it the interval grows with that travel::

    over-reading  = fixed + rate·s + location accuracy + slip/slide allowance ahead
    under-reading = fixed + rate·s + location accuracy + slip/slide allowance behind

- s: the distance [m] counted since the LRBG;
- fixed + rate·s: the odometer's error law (:class:`OdometryAccuracy`). SUBSET-041's
  requirement, 5 m + 5 % (DOMAIN.md §6), is the default and the bound every law must keep
  within; the wheel-sensor odometer of :mod:`onboard.etcs.odometer` models its own, tighter
  law (:meth:`onboard.etcs.odometer.OdometerParameters.accuracy`);
- location accuracy: the LRBG's Q_LOCACC (the linking information's when the group was
  announced, the national Q_NVLOCACC otherwise), plus the balise reader's own location error
  when the group comes from a reader (:meth:`onboard.etcs.EtcsOnboard.step_on_sensors`);
- slip/slide allowances: what the odometer added while it saw wheel slip or slide, when the
  wheels no longer measure the ground (:mod:`onboard.etcs.odometer`); 0 on the plain path.

Reading a balise group relocates the train on the group and restarts the interval. Then::

    max-safe front end = estimated + over-reading    (the true front end may be that far ahead)
    min-safe front end = estimated − under-reading   (or that far behind)

Locations are in the onboard's track coordinate (chainage, unwrapped on a ring).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from onboard.etcs._exceptions import EtcsInputError, TrainDataError

__all__ = [
    "SUBSET_041_ACCURACY",
    "ConfidenceInterval",
    "Odometry",
    "OdometryAccuracy",
]


@dataclass(frozen=True, kw_only=True)
class OdometryAccuracy:
    """The odometer's error law: ``fixed_error_m`` [m] plus ``proportional_error`` of s.

    The default is SUBSET-041's requirement (DOMAIN.md §6): ±(5 m + 5 %·s).
    """

    fixed_error_m: float = 5.0
    proportional_error: float = 0.05

    def __post_init__(self) -> None:
        if not (
            math.isfinite(self.fixed_error_m)
            and self.fixed_error_m >= 0.0
            and 0.0 <= self.proportional_error < 1.0
        ):
            raise TrainDataError("odometry accuracy needs a fixed error ≥ 0 and 0 ≤ rate < 1")

    def error_m(self, travelled_m: float) -> float:
        """The odometer's share of the interval [m] after ``travelled_m`` [m]."""
        return self.fixed_error_m + self.proportional_error * abs(travelled_m)

    def within(self, requirement: OdometryAccuracy) -> bool:
        """Whether this law never exceeds ``requirement``'s, whatever the distance."""
        return (
            self.fixed_error_m <= requirement.fixed_error_m
            and self.proportional_error <= requirement.proportional_error
        )


SUBSET_041_ACCURACY = OdometryAccuracy()
"""SUBSET-041's odometry accuracy requirement, ±(5 m + 5 %·s) (DOMAIN.md §6)."""


@dataclass(frozen=True, kw_only=True)
class ConfidenceInterval:
    """Where the front end is [m]: estimated, and the interval around it.

    ``over_reading_m`` lies ahead of the estimate (towards the max-safe front end),
    ``under_reading_m`` behind it (towards the min-safe front end).
    """

    estimated_front_m: float
    over_reading_m: float
    under_reading_m: float
    travelled_since_reference_m: float
    """The distance [m] counted since the LRBG (or the start), s of the error law."""
    location_accuracy_m: float = 0.0
    """The reference's share of both sides [m]: Q_LOCACC or Q_NVLOCACC, with the reader's."""
    slip_slide_over_reading_m: float = 0.0
    """The share of ``over_reading_m`` [m] added during wheel slip or slide since the LRBG."""
    slip_slide_under_reading_m: float = 0.0
    """The share of ``under_reading_m`` [m] added during wheel slip or slide since the LRBG."""

    @property
    def max_safe_front_m(self) -> float:
        """The front end's furthest possible location [m]."""
        return self.estimated_front_m + self.over_reading_m

    @property
    def min_safe_front_m(self) -> float:
        """The front end's nearest possible location [m]."""
        return self.estimated_front_m - self.under_reading_m

    def contains(self, location_m: float) -> bool:
        """Whether ``location_m`` [m] lies in [min-safe, max-safe]."""
        return self.min_safe_front_m <= location_m <= self.max_safe_front_m


def _check_finite(*values: float) -> None:
    if not all(math.isfinite(value) for value in values):
        raise EtcsInputError("odometer readings and allowances must be finite")


class Odometry:
    """The estimated front end and its confidence interval, relocated at balise groups.

    The odometer gives a distance [m] and, optionally, its cumulative slip/slide allowances
    ahead and behind [m] (they only grow); the interval takes what they added since the
    reference.

    Parameters
    ----------
    accuracy : OdometryAccuracy
        The error law.
    odometer_m : float
        Odometer reading [m] at start, taken as the reference's location.
    location_accuracy_m : float
        Accuracy [m] of that starting location (Q_NVLOCACC when nothing better is known).
    """

    def __init__(
        self, accuracy: OdometryAccuracy, *, odometer_m: float, location_accuracy_m: float
    ) -> None:
        self.accuracy = accuracy
        self._reference_location_m = 0.0
        self._reference_odometer_m = 0.0
        self._reference_over_m = 0.0
        self._reference_under_m = 0.0
        self._location_accuracy_m = 0.0
        self._odometer_m = odometer_m
        self._over_m = 0.0
        self._under_m = 0.0
        self.reset(
            location_m=odometer_m, odometer_m=odometer_m, location_accuracy_m=location_accuracy_m
        )

    def reset(
        self,
        *,
        location_m: float,
        odometer_m: float,
        location_accuracy_m: float,
        slip_slide_over_m: float = 0.0,
        slip_slide_under_m: float = 0.0,
    ) -> None:
        """The front end was at ``location_m`` [m] (a balise group) when the odometer read
        ``odometer_m`` [m] and its slip/slide allowances were ``slip_slide_over_m`` and
        ``slip_slide_under_m`` [m]; the interval restarts from ``location_accuracy_m`` [m]."""
        _check_finite(location_m, odometer_m, slip_slide_over_m, slip_slide_under_m)
        if not (math.isfinite(location_accuracy_m) and location_accuracy_m >= 0.0):
            raise EtcsInputError("an odometry reference needs a finite accuracy ≥ 0")
        self._reference_location_m = location_m
        self._reference_odometer_m = odometer_m
        self._reference_over_m = slip_slide_over_m
        self._reference_under_m = slip_slide_under_m
        self._location_accuracy_m = location_accuracy_m

    def update(
        self,
        odometer_m: float,
        *,
        slip_slide_over_m: float = 0.0,
        slip_slide_under_m: float = 0.0,
    ) -> ConfidenceInterval:
        """The interval at this odometer reading [m] and cumulative allowances [m]."""
        _check_finite(odometer_m, slip_slide_over_m, slip_slide_under_m)
        self._odometer_m = odometer_m
        self._over_m, self._under_m = slip_slide_over_m, slip_slide_under_m
        return self.interval

    def interval_at(
        self,
        odometer_m: float,
        *,
        slip_slide_over_m: float = 0.0,
        slip_slide_under_m: float = 0.0,
    ) -> ConfidenceInterval:
        """The interval at another reading, from the same reference; nothing is kept."""
        travelled_m = odometer_m - self._reference_odometer_m
        error_m = self.accuracy.error_m(travelled_m) + self._location_accuracy_m
        over_m = max(slip_slide_over_m - self._reference_over_m, 0.0)
        under_m = max(slip_slide_under_m - self._reference_under_m, 0.0)
        return ConfidenceInterval(
            estimated_front_m=self._reference_location_m + travelled_m,
            over_reading_m=error_m + over_m,
            under_reading_m=error_m + under_m,
            travelled_since_reference_m=abs(travelled_m),
            location_accuracy_m=self._location_accuracy_m,
            slip_slide_over_reading_m=over_m,
            slip_slide_under_reading_m=under_m,
        )

    @property
    def interval(self) -> ConfidenceInterval:
        """The interval at the last reading."""
        return self.interval_at(
            self._odometer_m, slip_slide_over_m=self._over_m, slip_slide_under_m=self._under_m
        )
