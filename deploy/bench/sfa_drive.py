"""A plant driven along a speed profile: the truth the sensor emulator samples.

A deliberately simple driver (not the ADF): it tracks the lower of a cruise speed and the line's
speed limit a braking distance ahead, with a proportional force law on the point-mass plant of
:mod:`onboard.plant.point_mass`, and brakes to a stop before the end of a line that is not a
ring. It exists so that the sensor-fusion chain can be exercised and measured on its own
(:mod:`deploy.bench.sfa_lockstep`, :mod:`deploy.bench.sfa_emulator`); :class:`DriveSettings`
says which drive, with which sensors and faults.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field

from onboard.plant.point_mass import URV_PARAMETERS, PointMassModel, PointMassParameters
from onboard.plant.sensors import SensorFaults, SensorNoise, TruthSample
from onboard.sfa.link import LinkFaults
from onboard.sfa.listener import ListenerConfig
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap

__all__ = ["DriveSettings", "SpeedProfileDrive"]

PLANNING_DECELERATION_MPS2 = 0.5
END_MARGIN_M = 300.0
SPEED_GAIN_PER_S = 0.8


@dataclass(frozen=True, kw_only=True)
class DriveSettings:
    """One emulated drive: the line, how it is driven, the sensors and the faults."""

    line_id: str = "bologna-ring"
    duration_s: float = 600.0
    cruise_kmh: float = 80.0
    start_m: float = 0.0
    seed: int = 0
    noise: SensorNoise = field(default_factory=SensorNoise)
    sensor_faults: SensorFaults = field(default_factory=SensorFaults)
    link_faults: LinkFaults = field(default_factory=LinkFaults)
    listener: ListenerConfig = field(default_factory=ListenerConfig)
    record: bool = False


class SpeedProfileDrive:
    """Truth samples every ``dt_s`` from a point-mass plant under a speed-profile driver.

    Parameters
    ----------
    track_map : TrackMap
        The line.
    start_m : float
        Starting chainage [m], standing still.
    cruise_kmh : float
        Cruise speed [km/h], capped by the line's limits.
    dt_s : float
        Plant step and sample interval [s].
    """

    def __init__(
        self,
        track_map: TrackMap,
        *,
        start_m: float = 0.0,
        cruise_kmh: float = 80.0,
        dt_s: float = 0.01,
        parameters: PointMassParameters = URV_PARAMETERS,
    ) -> None:
        self.track_map = track_map
        self.cruise_mps = cruise_kmh * MPS_PER_KMH
        self.dt_s = dt_s
        self.plant = PointMassModel(parameters, position_m=start_m)
        self.time_s = 0.0
        self._steps = 0

    def target_speed_mps(self, position_m: float, speed_mps: float) -> float:
        """The speed the driver aims at [m/s] here."""
        track_map = self.track_map
        target = self.cruise_mps
        horizon_m = speed_mps * speed_mps / (2.0 * PLANNING_DECELERATION_MPS2) + 50.0
        for fraction in (0.0, 0.25, 0.5, 0.75, 1.0):
            ahead_m = fraction * horizon_m
            limit = 0.95 * track_map.speed_limit_mps(position_m + ahead_m)
            reachable = math.sqrt(limit * limit + 2.0 * PLANNING_DECELERATION_MPS2 * ahead_m)
            target = min(target, reachable)
        if not track_map.line.ring:
            to_end_m = max(track_map.length_m - END_MARGIN_M - position_m, 0.0)
            target = min(target, math.sqrt(2.0 * PLANNING_DECELERATION_MPS2 * to_end_m))
        return target

    def sample(self) -> TruthSample:
        plant = self.plant
        return TruthSample(
            time_s=self.time_s,
            position_m=plant.position_m,
            speed_mps=plant.speed_mps,
            acceleration_mps2=plant.acceleration_mps2,
        )

    def step(self) -> TruthSample:
        """Advance one ``dt_s`` and return the truth at the new instant."""
        plant, track_map = self.plant, self.track_map
        position, speed = plant.position_m, plant.speed_mps
        target = self.target_speed_mps(position, speed)
        mass = plant.parameters.mass_kg
        demand = mass * SPEED_GAIN_PER_S * (target - speed) + plant.resistance_n(
            speed, track_map.gradient_permille(position), track_map.curve_radius_m(position)
        )
        plant.step(
            self.dt_s,
            demand,
            gradient_permille=track_map.gradient_permille(position),
            curve_radius_m=track_map.curve_radius_m(position),
        )
        self._steps += 1
        self.time_s = self._steps * self.dt_s
        return self.sample()

    def run(self, duration_s: float) -> Iterator[TruthSample]:
        """The samples of ``duration_s`` [s], the starting one first."""
        yield self.sample()
        for _ in range(round(duration_s / self.dt_s)):
            yield self.step()
