"""Headways between journeys on one line: plans of several trains that do not conflict.

The RBC's moving block (``trackside.separation``) keeps trains apart whatever they plan; a
train whose plan runs it into the one ahead is held by its MA and arrives late. The trackside
plans instead, before a journey is sent, so that the plans themselves keep the trains apart.

A journey's **nominal run** is where its train is planned to be, second by second, from the
journey's start (its acceptance on board, the origin of its timing points' times):

- standing at its start until its first leg departs, at 0;
- each leg between stopping timing points a plain LSPB, as the ADF's plain planner runs it
  (``onboard/adf/odp.py``): the comfort acceleration both ways and the cruising speed that
  covers the leg from the previous departure to the arrival time; a leg too short for its
  time at that acceleration is run as a triangle and arrives late;
- standing through each dwell, and at its end of journey for good: the train stays on the
  line. Passing points are passed on the way (their times are not modelled).

The ADF's energy-optimal plan is not an LSPB; where the two differ, the buffer time of
:class:`HeadwayRule` takes it up.

Two runs **conflict** when, at some time, the train behind is moving and the gap from its front
end to the rear end of the train ahead is less than the gap it needs not to be held by its MA:
the RBC's margin, a buffer for the two trains' odometry intervals, and the distance within
which the ADF plans a stop for its EoA (``reaction_s`` of look-ahead and a braking at
``deceleration_mps2`` from the highest speed it may run at, its journey's cap, as
``onboard/adf/replanning`` reaches: a train nearer its EoA runs to it and stands).
The train behind is taken a buffer time ahead of its nominal run, for
the ADF's run, which is not an LSPB, and for the train ahead's small delays. A train standing is
never the cause of a conflict: the train ahead of it moves off, or stands too.

Trains run towards increasing chainage, as on every line we hold. On a line, the train ahead is
the one whose front end is ahead at the start; on a ring each train is behind the other, the
gap taken round the lap. Nothing here reads a clock or a database: runs are placed on a common
time axis by their callers (``trackside.journey_planner``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import numpy.typing as npt

from protocol import messages as m
from trackdb.journey import Journey, JourneyTimingPoint

__all__ = [
    "COMFORT_ACCELERATION_MPS2",
    "Conflict",
    "HeadwayRule",
    "NominalRun",
    "PlacedRun",
    "PlannedStop",
    "PlanningMode",
    "delayed_journey",
    "earliest_delay",
    "first_conflict",
    "nominal_run",
    "planned_stops",
]

COMFORT_ACCELERATION_MPS2 = 0.5
"""The plain LSPB's acceleration and braking, the ADF's comfort values [m/s²]."""
STEP_S = 1.0
"""The nominal run's sampling [s]."""

Floats = npt.NDArray[np.float64]


class PlanningMode(StrEnum):
    """What the trackside does with a journey whose plan conflicts with another train's."""

    ADJUST = "adjust"
    """Delay it until it clears."""
    CHECK = "check"
    """Refuse it."""
    OFF = "off"
    """Nothing: the moving block alone keeps the trains apart."""


@dataclass(frozen=True, kw_only=True)
class HeadwayRule:
    """The gap a moving train needs behind the train ahead not to be held by its MA."""

    margin_m: float
    """The RBC's margin behind the min safe rear end of the train ahead [m]."""
    buffer_m: float = 40.0
    """The two trains' odometry intervals [m]."""
    buffer_s: float = 30.0
    """Buffer time: the train behind is taken this much ahead of its nominal run [s]. The ADF's
    energy-optimal run holds a higher speed than the LSPB and coasts to the stop, so it comes
    near the stop earlier (by 20 s on two-trains-planned's first leg), and the train ahead may
    leave a stop a few seconds late."""
    reaction_s: float = 6.0
    """The ADF's look-ahead before it brakes for an EoA [s]."""
    deceleration_mps2: float = 0.5
    """The ADF's braking for an EoA [m/s²]."""

    def required_gap_m(self, speed_mps: Floats) -> Floats:
        v: Floats = np.asarray(speed_mps, dtype=np.float64)
        braking: Floats = v * self.reaction_s + v * v / (2.0 * self.deceleration_mps2)
        return braking + (self.margin_m + self.buffer_m)


@dataclass(frozen=True, slots=True)
class PlannedStop:
    """A stopping timing point as distance travelled from the journey's start and its times."""

    travelled_m: float
    arrival_s: float
    departure_s: float


@dataclass(frozen=True)
class NominalRun:
    """Distance travelled [m] and speed [m/s] every :data:`STEP_S` from the journey's start;
    before it the train stands at its start, after it at its last position."""

    travelled_m: Floats
    speed_mps: Floats

    @property
    def end_s(self) -> float:
        return (len(self.travelled_m) - 1) * STEP_S

    def at(self, t_s: Floats) -> tuple[Floats, Floats]:
        """Distance travelled and speed at times ``t_s`` from the journey's start."""
        grid = np.arange(len(self.travelled_m)) * STEP_S
        travelled = np.interp(t_s, grid, self.travelled_m)
        speed = np.interp(t_s, grid, self.speed_mps, left=0.0, right=0.0)
        return travelled, speed


def planned_stops(journey: Journey, distances_m: Sequence[float]) -> list[PlannedStop]:
    """The journey's stopping timing points, ``distances_m`` the distance travelled to each
    of its timing points (``JourneyCheck.distances_m``)."""
    stops = []
    for point, travelled in zip(journey.timing_points, distances_m, strict=True):
        if point.kind is not m.TimingPointKind.STOPPING:
            continue
        stops.append(PlannedStop(travelled, point.arrival_time_s, _departure_s(point)))
    return stops


def _departure_s(point: JourneyTimingPoint) -> float:
    """When the train leaves a stopping point, as the ADF reads it (``onboard/adf/journey``)."""
    if point.departure_time_s is None:
        return point.arrival_time_s
    return max(point.departure_time_s, point.arrival_time_s + point.minimum_dwell_s)


def nominal_run(
    stops: Sequence[PlannedStop], acceleration_mps2: float = COMFORT_ACCELERATION_MPS2
) -> NominalRun:
    """The nominal run through ``stops``, legs from standstill to standstill."""
    travelled = [np.zeros(1)]
    speed = [np.zeros(1)]
    here_m, now_s, ready_s = 0.0, 0.0, 0.0
    for stop in stops:
        distance = stop.travelled_m - here_m
        if distance <= 0.0:
            continue
        duration = _leg_duration_s(distance, stop.arrival_s - ready_s, acceleration_mps2)
        arrival = ready_s + duration
        last = max(math.ceil(arrival / STEP_S) * STEP_S, now_s + STEP_S)
        grid = np.arange(now_s + STEP_S, last + STEP_S / 2, STEP_S)
        leg_x, leg_v = _trapezoid(grid - ready_s, distance, duration, acceleration_mps2)
        travelled.append(here_m + leg_x)
        speed.append(leg_v)
        here_m, now_s = stop.travelled_m, float(grid[-1])
        ready_s = max(stop.departure_s, arrival)
    return NominalRun(np.concatenate(travelled), np.concatenate(speed))


def _leg_duration_s(distance_m: float, scheduled_s: float, a: float) -> float:
    """The scheduled running time, or the triangle's when the leg cannot be run in it."""
    return max(scheduled_s, 2.0 * math.sqrt(distance_m / a))


def _trapezoid(
    t_s: Floats, distance_m: float, duration_s: float, a: float
) -> tuple[Floats, Floats]:
    """Distance and speed at ``t_s`` (from departure) of an LSPB covering ``distance_m`` in
    ``duration_s``, standing before and after."""
    root = max((a * duration_s) ** 2 - 4.0 * a * distance_m, 0.0)
    cruise = (a * duration_s - math.sqrt(root)) / 2.0
    ramp = cruise / a
    t = np.clip(t_s, 0.0, duration_s)
    up = np.minimum(t, ramp)
    down = np.clip(t - (duration_s - ramp), 0.0, ramp)
    travelled = 0.5 * a * up**2 + cruise * np.clip(t - ramp, 0.0, duration_s - 2 * ramp)
    travelled = travelled + cruise * down - 0.5 * a * down**2
    speed = np.where(t < ramp, a * t, np.where(t > duration_s - ramp, a * (duration_s - t), cruise))
    speed = np.where((t_s <= 0.0) | (t_s >= duration_s), 0.0, speed)
    return np.minimum(travelled, distance_m), np.maximum(speed, 0.0)


@dataclass(frozen=True)
class PlacedRun:
    """A train's nominal run placed on the common time axis of a planning."""

    vehicle_id: str
    start_m: float
    """Chainage of the train's front end at the run's start [m]."""
    length_m: float
    run: NominalRun = field(default_factory=lambda: nominal_run(()))
    """A train without a journey stands at its start."""
    started_s: float = 0.0
    """The run's start on the common axis: below 0 for a journey under way [s]."""
    top_speed_mps: float | None = None
    """The highest speed the train may run at (its journey's cap) [m/s]: the ADF plans a stop
    for its EoA once that lies within the braking from it, however slowly it runs. ``None``:
    the nominal run's speed."""

    @property
    def end_s(self) -> float:
        return self.started_s + self.run.end_s

    def front_m(self, t_s: Floats) -> tuple[Floats, Floats]:
        """Front-end chainage (unwrapped) and speed at common times ``t_s``."""
        travelled, speed = self.run.at(t_s - self.started_s)
        return self.start_m + travelled, speed


@dataclass(frozen=True, slots=True)
class Conflict:
    """The first time a moving train comes closer to the train ahead than the rule allows."""

    behind: str
    ahead: str
    at_s: float
    """On the common axis [s]."""
    gap_m: float
    required_m: float

    def __str__(self) -> str:
        return (
            f"{self.behind} would run {self.gap_m:.0f} m behind {self.ahead} at "
            f"+{self.at_s:.0f} s ({self.required_m:.0f} m needed)"
        )


def first_conflict(
    run: PlacedRun,
    others: Sequence[PlacedRun],
    rule: HeadwayRule,
    *,
    ring_length_m: float | None,
) -> Conflict | None:
    """The first conflict of ``run`` with any of ``others`` from time 0 on, ``None`` when its
    plan keeps clear of them all (and theirs of it)."""
    horizon = max([run.end_s, *(other.end_s for other in others)]) + STEP_S
    t = np.arange(0.0, max(horizon, 0.0) + STEP_S / 2, STEP_S)
    found: list[Conflict] = []
    for other in others:
        for behind, ahead in _pairs(run, other, ring_length_m):
            conflict = _pair_conflict(behind, ahead, t, rule, ring_length_m)
            if conflict is not None:
                found.append(conflict)
    return min(found, key=lambda c: c.at_s, default=None)


def _pairs(
    a: PlacedRun, b: PlacedRun, ring_length_m: float | None
) -> list[tuple[PlacedRun, PlacedRun]]:
    """(behind, ahead): both orders on a ring, the order at the start on a line."""
    if ring_length_m is not None:
        return [(a, b), (b, a)]
    a_front = float(a.front_m(np.zeros(1))[0][0])
    b_front = float(b.front_m(np.zeros(1))[0][0])
    return [(a, b)] if a_front <= b_front else [(b, a)]


def _pair_conflict(
    behind: PlacedRun,
    ahead: PlacedRun,
    t: Floats,
    rule: HeadwayRule,
    ring_length_m: float | None,
) -> Conflict | None:
    front, speed = behind.front_m(t + rule.buffer_s)
    ahead_front, _ = ahead.front_m(t)
    gap = ahead_front - ahead.length_m - front
    if ring_length_m is not None:
        # The lap between them is read once, at the start, where they stand: the gap then
        # runs on unwrapped, and one that the train behind would close falls below 0 rather
        # than wrapping to a lap.
        now_behind, _ = behind.front_m(t[:1])
        now_gap = float(ahead_front[0] - ahead.length_m - now_behind[0])
        gap = gap + (now_gap % ring_length_m - now_gap)
    reach_speed = (
        speed if behind.top_speed_mps is None else np.full_like(speed, behind.top_speed_mps)
    )
    required = rule.required_gap_m(reach_speed)
    short = np.flatnonzero((speed > 0.0) & (gap < required))
    if not len(short):
        return None
    i = int(short[0])
    return Conflict(
        behind.vehicle_id, ahead.vehicle_id, float(t[i]), float(gap[i]), float(required[i])
    )


def earliest_delay(
    candidate: Callable[[float], PlacedRun],
    others: Sequence[PlacedRun],
    rule: HeadwayRule,
    *,
    ring_length_m: float | None,
    max_delay_s: float,
    step_s: float,
) -> tuple[float | None, Conflict | None]:
    """The least delay, in steps of ``step_s`` up to ``max_delay_s``, by which a journey keeps
    clear of ``others``: (delay, the conflict at no delay); (``None``, the conflict at the
    longest delay) when none does. ``candidate(delay)`` places the journey delayed by it."""
    undelayed: Conflict | None = None
    delay = 0.0
    while True:
        conflict = first_conflict(candidate(delay), others, rule, ring_length_m=ring_length_m)
        if delay == 0.0:
            undelayed = conflict
        if conflict is None:
            return delay, undelayed
        if delay + step_s > max_delay_s + 1e-9:
            return None, conflict
        delay += step_s


def delayed_journey(journey: Journey, delay_s: float) -> Journey:
    """The journey with every timing point's times ``delay_s`` later: the first leg then takes
    longer, and every later one keeps its running time."""
    points = tuple(
        point.model_copy(
            update={
                "arrival_time_s": point.arrival_time_s + delay_s,
                "departure_time_s": (
                    None if point.departure_time_s is None else point.departure_time_s + delay_s
                ),
            }
        )
        for point in journey.timing_points
    )
    return journey.model_copy(update={"timing_points": points})
