"""The axle-end sensors: each wheelset's rotation as the calibrated wheel diameter converts it.

A tachometer or pulse generator on an axle counts the wheel's rotation; the onboard turns it
into a distance with the wheel diameter it was calibrated with. The real diameter shrinks with
wear between reprofilings (a wheel loses up to about 1–2 % of its diameter), so the reading is
off by a scale factor: with ``diameter_error`` = calibrated / real − 1, a worn wheel
(``diameter_error`` > 0) reads long. Slip (a wheel turning faster than the vehicle runs) and
slide (slower) need no model here: on the bogie model each wheel's own rotation is integrated,
so they show in the reading as they would on a real train. On the point-mass model the wheels
roll without slip and the reading is the body's travel.

The reading is continuous (:class:`~onboard.plant.readings.WheelReading`): each consumer
(ETCS odometry, the VC's tachometer board, the VCU) quantises it into its own pulses.
Error sources and values: docs/sensors.md.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from onboard.plant.interfaces import BogieTruth
from onboard.plant.readings import WheelReading

if TYPE_CHECKING:
    from onboard.plant.sensors import TruthSample

__all__ = [
    "DIAMETER_ERROR_BOUND_SIGMAS",
    "DIAMETER_ERROR_SIGMA",
    "PulseCounter",
    "WheelSensors",
    "draw_diameter_error",
]

DIAMETER_ERROR_SIGMA = 0.002
"""σ of the calibrated-over-real wheel diameter ratio's error (0.2 %): the wear since the last
calibration. A wheel loses up to about 1–2 % of its diameter between reprofilings; regular
recalibration keeps the residual error a fraction of that."""
DIAMETER_ERROR_BOUND_SIGMAS = 3.0
"""A drawn diameter error lies within this many σ; an explicit ``diameter_error`` may not."""


def draw_diameter_error(rng: np.random.Generator, sigma: float = DIAMETER_ERROR_SIGMA) -> float:
    """A wheel-diameter error (calibrated / real − 1, dimensionless) drawn from ``rng``.

    Normal with σ ``sigma``, redrawn until it lies within ±3 σ
    (:data:`DIAMETER_ERROR_BOUND_SIGMAS`). One draw serves every sensor that reads the same
    wheels (the axle sensors and a wheel-based odometer channel), so that they agree.

    Parameters
    ----------
    rng : numpy.random.Generator
        The source of randomness.
    sigma : float
        σ of the error (dimensionless, 0.002 = 0.2 %); 0 gives 0 and draws nothing.
    """
    if sigma <= 0.0:
        return 0.0
    bound = DIAMETER_ERROR_BOUND_SIGMAS * sigma
    while True:
        error = float(rng.normal(0.0, sigma))
        if abs(error) <= bound:
            return error


class WheelSensors:
    """The plant's truth in, the axle sensors' :class:`WheelReading` out, one tick at a time.

    Parameters
    ----------
    rng : numpy.random.Generator
        Draws the diameter error when none is given (one draw, at construction).
    diameter_error : float, optional
        Calibrated over real wheel diameter minus 1 (dimensionless), both axles: +0.02 reads
        2 % long. By default drawn with :func:`draw_diameter_error`.
    diameter_error_sigma : float
        σ of the drawn error (dimensionless).

    Notes
    -----
    Travel counts from the first :meth:`step` (the sensors' power-up). On the bogie model each
    wheel's angular speed [rad/s] is integrated with the trapezoidal rule between steps and
    multiplied by the wheel radius; on the point-mass model (a :class:`TruthSample` without
    wheel speeds) the travel is the body's, from its position.
    """

    def __init__(
        self,
        *,
        rng: np.random.Generator,
        diameter_error: float | None = None,
        diameter_error_sigma: float = DIAMETER_ERROR_SIGMA,
    ) -> None:
        if diameter_error is None:
            diameter_error = draw_diameter_error(rng, diameter_error_sigma)
        if not diameter_error > -1.0:
            raise ValueError("diameter_error must be above -1")
        self.diameter_error = diameter_error
        self._scale = 1.0 + diameter_error
        self._last: tuple[float, float, float] | None = None
        """(time [s], front, rear circumferential speed [m/s]) at the last step."""
        self._origin_m = 0.0
        self._travel_front_m = 0.0
        self._travel_rear_m = 0.0

    def step(self, truth: BogieTruth | TruthSample) -> WheelReading:
        """The reading at ``truth.time_s``.

        Parameters
        ----------
        truth : BogieTruth or TruthSample
            The plant's truth now: the bogie model's (each wheel's rotation) or a sample of the
            point-mass model's (no slip; its wheel speeds, when given, are used instead).

        Returns
        -------
        WheelReading
            Each axle's travel since the first step [m] and speed [m/s], scaled by
            ``1 + diameter_error``.
        """
        time_s = truth.time_s
        if isinstance(truth, BogieTruth):
            radius_m = truth.wheel_radius_m
            front_mps = truth.wheel_speed_front_radps * radius_m
            rear_mps = truth.wheel_speed_rear_radps * radius_m
        elif truth.wheel_speed_mps is not None:
            front_mps = truth.wheel_speed_mps
            rear_mps = (
                front_mps if truth.wheel_speed_rear_mps is None else truth.wheel_speed_rear_mps
            )
        else:
            return self._body_reading(time_s, truth.position_m, truth.speed_mps)
        last = self._last
        if last is not None:
            half_dt_s = 0.5 * (time_s - last[0])
            self._travel_front_m += half_dt_s * (last[1] + front_mps)
            self._travel_rear_m += half_dt_s * (last[2] + rear_mps)
        self._last = (time_s, front_mps, rear_mps)
        scale = self._scale
        return WheelReading(
            time_s=time_s,
            travel_front_m=scale * self._travel_front_m,
            travel_rear_m=scale * self._travel_rear_m,
            speed_front_mps=scale * front_mps,
            speed_rear_mps=scale * rear_mps,
        )

    def _body_reading(self, time_s: float, position_m: float, speed_mps: float) -> WheelReading:
        if self._last is None:
            self._origin_m = position_m
        self._last = (time_s, speed_mps, speed_mps)
        scale = self._scale
        travel_m = scale * (position_m - self._origin_m)
        speed = scale * speed_mps
        return WheelReading(
            time_s=time_s,
            travel_front_m=travel_m,
            travel_rear_m=travel_m,
            speed_front_mps=speed,
            speed_rear_mps=speed,
        )


class PulseCounter:
    """A pulse counter on a wheel: the travel a :class:`WheelReading` gives, in whole counts,
    and the speed over a sample interval as the counts since the last sample over the time.

    The quantisation error of a speed sample is the difference of two rounding errors of one
    count: zero mean, variance (``count_m`` / interval)² / 6; summed over samples it does not
    drift, as the counts are not lost.

    Parameters
    ----------
    count_m : float
        Travel per count [m]; 0 or less turns quantisation off (the speed passes through).
    """

    def __init__(self, count_m: float) -> None:
        self.count_m = count_m
        self.count: int | None = None
        """Counts at the last sample; None before the first."""
        self._time_s = 0.0

    def speed(self, travel_m: float, speed_mps: float, time_s: float, period_s: float) -> float:
        """The measured speed [m/s] of a sample at ``time_s`` [s].

        Parameters
        ----------
        travel_m : float
            The wheel's travel reading now [m].
        speed_mps : float
            Its speed reading now [m/s]: the first sample (no count before it) quantises it to
            the resolution of a ``period_s`` interval; otherwise unused.
        time_s, period_s : float
            The sample's instant and the nominal interval between samples [s].
        """
        count_m = self.count_m
        if count_m <= 0.0:
            return speed_mps
        count = math.floor(travel_m / count_m)
        last_count, self.count = self.count, count
        elapsed_s, self._time_s = time_s - self._time_s, time_s
        if last_count is None or elapsed_s <= 0.0:
            resolution_mps = count_m / period_s
            return round(speed_mps / resolution_mps) * resolution_mps
        return (count - last_count) * count_m / elapsed_s
