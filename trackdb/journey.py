"""Journeys: planned runs on a line, their validation, and the journey profile sent on board.

A journey starts at a chainage and visits timing points (TP) in the direction of travel: stopping
points, where the train stops at least the minimum dwell, passing points, where it only passes,
and points to skip. Exactly one TP is the end of journey, and it is the last (SUBSET-125 §6.4).

Validation against the line (:func:`check_journey`) lists every problem: TPs off the line or not
following the direction of travel (on a ring each TP is the next occurrence of its chainage
ahead of the previous one), references to unknown stopping points, and legs that cannot be run
in time. A leg is feasible when the minimum running time under the most restrictive speed profile
(line speed, TSRs and the journey's cap), the vehicle's traction (force and power) and its
service braking, from standstill at stopping points, is at most the scheduled time; otherwise the
leg and the shortfall [s] are named.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Self

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from protocol import messages as m
from protocol.units import GRAVITY_MPS2
from trackdb.schema import Identifier
from trackdb.track_map import TrackMap
from trackdb.vehicle import URV_MAX_SPEED_MPS, URV_PARAMETERS, PointMassParameters

__all__ = [
    "URV_LIMITS",
    "Journey",
    "JourneyCheck",
    "JourneyTimingPoint",
    "LegCheck",
    "VehicleLimits",
    "check_journey",
    "journey_profile_message",
    "minimum_running_times",
]

DEFAULT_STEP_M = 5.0
MAX_SAMPLES = 40_000
URV_SERVICE_DECELERATION_MPS2 = 0.6
"""The URV's service braking as planned: within the timetable range of DOMAIN.md §4 [m/s²]."""


@dataclass(frozen=True, kw_only=True)
class VehicleLimits:
    """What the planner needs to know of the vehicle, SI units."""

    mass_kg: float
    rotating_mass_factor: float
    max_traction_force_n: float
    max_traction_power_w: float
    service_deceleration_mps2: float
    max_speed_mps: float

    @classmethod
    def of(
        cls,
        vehicle: PointMassParameters,
        *,
        service_deceleration_mps2: float,
        max_speed_mps: float,
    ) -> VehicleLimits:
        """The limits of ``vehicle``, braking as planned and capped at its maximum speed."""
        return cls(
            mass_kg=vehicle.mass_kg,
            rotating_mass_factor=vehicle.rotating_mass_factor,
            max_traction_force_n=vehicle.max_traction_force_n,
            max_traction_power_w=vehicle.max_traction_power_w,
            service_deceleration_mps2=service_deceleration_mps2,
            max_speed_mps=max_speed_mps,
        )


URV_LIMITS = VehicleLimits.of(
    URV_PARAMETERS,
    service_deceleration_mps2=URV_SERVICE_DECELERATION_MPS2,
    max_speed_mps=URV_MAX_SPEED_MPS,
)
"""The URV's (:mod:`trackdb.vehicle`): 15 t, 30 kN, 400 kW, 200 km/h."""


class JourneyTimingPoint(BaseModel):
    """A TP of a journey: where (a stopping point of the line, or a chainage) and when."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: Identifier
    stopping_point_id: Identifier | None = Field(default=None, description="Line stopping point")
    position_m: float | None = Field(
        default=None, ge=0.0, allow_inf_nan=False, description="Chainage [m], if no stop is named"
    )
    kind: m.TimingPointKind = m.TimingPointKind.STOPPING
    arrival_time_s: float = Field(ge=0.0, allow_inf_nan=False, description="From start [s]")
    arrival_window_s: float = Field(default=2.0, ge=0.0, allow_inf_nan=False, description="[s]")
    departure_time_s: float | None = Field(default=None, ge=0.0, allow_inf_nan=False)
    minimum_dwell_s: float = Field(default=0.0, ge=0.0, allow_inf_nan=False, description="[s]")
    stopping_tolerance_m: float | None = Field(
        default=None,
        ge=0.1,
        le=100.0,
        allow_inf_nan=False,
        description="± [m]; the stopping point's own tolerance when not given",
    )
    end_of_journey: bool = False

    @model_validator(mode="after")
    def _located_once(self) -> Self:
        if (self.stopping_point_id is None) == (self.position_m is None):
            raise ValueError("give either stopping_point_id or position_m")
        if self.departure_time_s is not None and self.departure_time_s < self.arrival_time_s:
            raise ValueError("departure before arrival")
        return self


class Journey(BaseModel):
    """A planned run: the line, where it starts, its speed cap and its timing points."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: Identifier
    line_id: Identifier
    start_position_m: float = Field(ge=0.0, allow_inf_nan=False, description="Start chainage [m]")
    max_speed_mps: float | None = Field(
        default=None, gt=0.0, le=150.0, allow_inf_nan=False, description="Journey cap [m/s]"
    )
    timing_points: tuple[JourneyTimingPoint, ...] = Field(min_length=1, max_length=500)


@dataclass(frozen=True)
class LegCheck:
    """One leg, from the previous TP (or the start) to a TP."""

    index: int
    from_id: str
    to_id: str
    distance_m: float
    scheduled_s: float
    minimum_s: float

    @property
    def shortfall_s(self) -> float:
        return max(0.0, self.minimum_s - self.scheduled_s)


@dataclass(frozen=True)
class JourneyCheck:
    problems: tuple[str, ...]
    legs: tuple[LegCheck, ...]
    positions_m: tuple[float, ...]
    """Chainage of each TP on the line."""
    distances_m: tuple[float, ...]
    """Distance travelled from the start to each TP."""

    @property
    def valid(self) -> bool:
        return not self.problems


def check_journey(
    journey: Journey, track_map: TrackMap, vehicle: VehicleLimits = URV_LIMITS
) -> JourneyCheck:
    """Validate a journey against its line; every problem is listed."""
    problems: list[str] = []
    line = track_map.line
    if journey.line_id != line.id:
        problems.append(f"journey is for line {journey.line_id!r}, not {line.id!r}")
    if journey.start_position_m >= line.length_m:
        problems.append(f"start {journey.start_position_m} m is beyond the line's end")
    problems += _check_end_of_journey(journey)
    positions = _positions(journey, track_map, problems)
    distances = _travel_distances(journey, track_map, positions, problems)
    if problems:
        return JourneyCheck(tuple(problems), (), tuple(positions), tuple(distances))
    legs = _legs(journey, track_map, vehicle, distances)
    for leg in legs:
        if leg.shortfall_s > 0.0:
            problems.append(
                f"leg {leg.index} ({leg.from_id} → {leg.to_id}, {leg.distance_m:.0f} m): "
                f"minimum running time {leg.minimum_s:.1f} s exceeds the scheduled "
                f"{leg.scheduled_s:.1f} s by {leg.shortfall_s:.1f} s"
            )
    return JourneyCheck(tuple(problems), tuple(legs), tuple(positions), tuple(distances))


def _check_end_of_journey(journey: Journey) -> list[str]:
    ends = [i for i, tp in enumerate(journey.timing_points) if tp.end_of_journey]
    if ends != [len(journey.timing_points) - 1]:
        return ["exactly one timing point must be the end of journey, and it must be the last"]
    if journey.timing_points[-1].kind is not m.TimingPointKind.STOPPING:
        return ["the end of journey must be a stopping point"]
    return []


def _positions(journey: Journey, track_map: TrackMap, problems: list[str]) -> list[float]:
    stops = {point.id: point.position_m for point in track_map.line.stopping_points}
    positions = []
    for index, tp in enumerate(journey.timing_points):
        if tp.stopping_point_id is not None:
            position = stops.get(tp.stopping_point_id)
            if position is None:
                problems.append(f"timing_points[{index}] {tp.id}: unknown stopping point")
                position = 0.0
        else:
            position = float(tp.position_m or 0.0)
            if position >= track_map.length_m:
                problems.append(f"timing_points[{index}] {tp.id}: beyond the line's end")
        positions.append(position)
    return positions


def _travel_distances(
    journey: Journey, track_map: TrackMap, positions: list[float], problems: list[str]
) -> list[float]:
    length = track_map.length_m
    previous_position = journey.start_position_m
    travelled = 0.0
    distances = []
    for index, (tp, position) in enumerate(zip(journey.timing_points, positions, strict=True)):
        if track_map.line.ring:
            ahead = (position - previous_position) % length
            if ahead == 0.0 and index > 0:
                ahead = length  # the same place again: one more lap
        else:
            ahead = position - previous_position
        if ahead <= 0.0 and not (index == 0 and ahead == 0.0):
            problems.append(
                f"timing_points[{index}] {tp.id}: at {position:.1f} m, not ahead of "
                f"{previous_position:.1f} m in the direction of travel"
            )
        travelled += max(ahead, 0.0)
        distances.append(travelled)
        previous_position = position
    return distances


def _legs(
    journey: Journey, track_map: TrackMap, vehicle: VehicleLimits, distances: list[float]
) -> list[LegCheck]:
    stops_at = [tp.kind is m.TimingPointKind.STOPPING for tp in journey.timing_points]
    minimum = minimum_running_times(
        track_map,
        vehicle,
        journey.start_position_m,
        distances,
        stops_at,
        cap_mps=journey.max_speed_mps,
    )
    legs = []
    departure = 0.0
    previous_id = "start"
    previous_distance = 0.0
    for index, tp in enumerate(journey.timing_points):
        legs.append(
            LegCheck(
                index=index,
                from_id=previous_id,
                to_id=tp.id,
                distance_m=distances[index] - previous_distance,
                scheduled_s=tp.arrival_time_s - departure,
                minimum_s=minimum[index],
            )
        )
        if tp.kind is m.TimingPointKind.STOPPING:
            departure = tp.departure_time_s or tp.arrival_time_s + tp.minimum_dwell_s
        else:
            departure = tp.arrival_time_s
        previous_id, previous_distance = tp.id, distances[index]
    return legs


def minimum_running_times(
    track_map: TrackMap,
    vehicle: VehicleLimits,
    start_m: float,
    distances_m: list[float],
    stops_at: list[bool],
    *,
    cap_mps: float | None = None,
    step_m: float = DEFAULT_STEP_M,
) -> list[float]:
    """Minimum running time [s] of each leg, from standstill at the start.

    Parameters
    ----------
    track_map
        The line.
    vehicle
        Traction and braking limits.
    start_m
        Start chainage [m].
    distances_m
        Distance travelled from the start to each timing point [m], increasing.
    stops_at
        Whether the train stops at each timing point.
    cap_mps
        Journey speed cap [m/s].
    step_m
        Integration step [m]; widened for long journeys to stay within ``MAX_SAMPLES``.
    """
    total = distances_m[-1]
    step = max(step_m, total / MAX_SAMPLES)
    count = max(2, math.ceil(total / step) + 1)
    s = np.linspace(0.0, total, count)
    cap = min(vehicle.max_speed_mps, cap_mps or math.inf)
    limit = np.array([min(track_map.mrsp_mps(start_m + x), cap) for x in s])
    gradient = np.array([track_map.gradient_permille(start_m + x) for x in s])
    marks = np.searchsorted(s, distances_m)
    marks = np.minimum(marks, count - 1)
    for mark, stop in zip(marks, stops_at, strict=True):
        if stop:
            limit[mark] = 0.0
    limit[0] = 0.0
    speed = _speed_envelope(s, limit, gradient, vehicle)
    mean = np.maximum(0.5 * (speed[1:] + speed[:-1]), 1e-3)
    elapsed = np.concatenate(([0.0], np.cumsum(np.diff(s) / mean)))
    times = elapsed[marks]
    return [float(t) for t in np.diff(np.concatenate(([0.0], times)))]


def _speed_envelope(
    s: np.ndarray, limit: np.ndarray, gradient: np.ndarray, vehicle: VehicleLimits
) -> np.ndarray:
    """Fastest speed profile under the limits: full traction forwards, service braking back."""
    mass = vehicle.mass_kg * (1.0 + vehicle.rotating_mass_factor)
    grade = GRAVITY_MPS2 * np.sin(np.arctan(gradient / 1000.0))
    forward = limit.astype(float).copy()
    for i in range(len(s) - 1):
        v = forward[i]
        force = min(vehicle.max_traction_force_n, vehicle.max_traction_power_w / max(v, 1.0))
        accel = force / mass - grade[i]
        reachable = math.sqrt(max(v * v + 2.0 * accel * (s[i + 1] - s[i]), 0.0))
        forward[i + 1] = min(forward[i + 1], reachable)
    backward = forward
    for i in range(len(s) - 2, -1, -1):
        decel = vehicle.service_deceleration_mps2
        reachable = math.sqrt(backward[i + 1] ** 2 + 2.0 * decel * (s[i + 1] - s[i]))
        backward[i] = min(backward[i], reachable)
    return backward


def journey_profile_message(
    journey: Journey,
    check: JourneyCheck,
    *,
    vehicle_id: str,
    version: int,
    track_data_version: str,
    status: m.JourneyProfileStatus = m.JourneyProfileStatus.VALID,
) -> m.JourneyProfile:
    """The journey profile to send on board, with chainages resolved."""
    if not check.valid:
        raise ValueError("only a valid journey becomes a journey profile")
    points = tuple(
        m.TimingPoint(
            id=tp.id,
            position_m=position,
            kind=tp.kind,
            arrival_time_s=tp.arrival_time_s,
            arrival_tolerance_s=tp.arrival_window_s,
            departure_time_s=tp.departure_time_s,
            minimum_dwell_s=tp.minimum_dwell_s,
            end_of_journey=tp.end_of_journey,
        )
        for tp, position in zip(journey.timing_points, check.positions_m, strict=True)
    )
    return m.JourneyProfile(
        vehicle_id=vehicle_id,
        journey_id=journey.id,
        version=version,
        status=status,
        line_id=journey.line_id,
        track_data_version=track_data_version,
        max_speed_mps=journey.max_speed_mps,
        timing_points=points,
    )
