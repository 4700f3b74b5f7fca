"""Odometry confidence interval: where the front end may be (SUBSET-026 §3.6.4; DOMAIN.md §6).

The estimated front end is the location of the last relevant balise group (LRBG) plus the
odometer's travel since it was passed. Around it the interval grows with that travel::

    over-reading = under-reading = 5 m + 5 %·s + Q_LOCACC

s being the distance [m] travelled since the LRBG (SUBSET-041's odometry accuracy, DOMAIN.md §6)
and Q_LOCACC the LRBG's location accuracy: the linking information's when the group was
announced, the national Q_NVLOCACC otherwise. Passing a balise group relocates the train on
the group and resets s to 0. Then::

    max-safe front end = estimated + over-reading
    min-safe front end = estimated − under-reading

Locations are in the onboard's track coordinate (chainage, unwrapped on a ring).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from onboard.etcs._exceptions import EtcsInputError, TrainDataError

__all__ = ["ConfidenceInterval", "Odometry", "OdometryAccuracy"]


@dataclass(frozen=True, kw_only=True)
class OdometryAccuracy:
    """The odometer's error law: ``fixed_error_m`` [m] plus ``proportional_error`` of s."""

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


@dataclass(frozen=True, kw_only=True)
class ConfidenceInterval:
    """Where the front end is [m]: estimated, and the interval around it."""

    estimated_front_m: float
    over_reading_m: float
    under_reading_m: float
    travelled_since_reference_m: float

    @property
    def max_safe_front_m(self) -> float:
        """The front end's furthest possible location [m]."""
        return self.estimated_front_m + self.over_reading_m

    @property
    def min_safe_front_m(self) -> float:
        """The front end's nearest possible location [m]."""
        return self.estimated_front_m - self.under_reading_m


class Odometry:
    """The estimated front end and its confidence interval, relocated at balise groups.

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
        self._location_accuracy_m = 0.0
        self._odometer_m = odometer_m
        self.reset(
            location_m=odometer_m, odometer_m=odometer_m, location_accuracy_m=location_accuracy_m
        )

    def reset(self, *, location_m: float, odometer_m: float, location_accuracy_m: float) -> None:
        """The front end was at ``location_m`` [m] (a balise group) when the odometer read
        ``odometer_m`` [m]; the interval restarts from ``location_accuracy_m`` [m]."""
        if not (
            math.isfinite(location_m)
            and math.isfinite(odometer_m)
            and math.isfinite(location_accuracy_m)
            and location_accuracy_m >= 0.0
        ):
            raise EtcsInputError("an odometry reference needs finite values and accuracy ≥ 0")
        self._reference_location_m = location_m
        self._reference_odometer_m = odometer_m
        self._location_accuracy_m = location_accuracy_m

    def update(self, odometer_m: float) -> ConfidenceInterval:
        """The interval at this odometer reading [m]."""
        if not math.isfinite(odometer_m):
            raise EtcsInputError(f"odometer reading {odometer_m} m is not finite")
        self._odometer_m = odometer_m
        return self.interval

    @property
    def interval(self) -> ConfidenceInterval:
        """The interval at the last reading."""
        travelled_m = self._odometer_m - self._reference_odometer_m
        error_m = self.accuracy.error_m(travelled_m) + self._location_accuracy_m
        return ConfidenceInterval(
            estimated_front_m=self._reference_location_m + travelled_m,
            over_reading_m=error_m,
            under_reading_m=error_m,
            travelled_since_reference_m=abs(travelled_m),
        )
