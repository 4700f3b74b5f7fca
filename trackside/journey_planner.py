"""The trackside's planning of several trains' journeys on one line (issue 23).

Before a journey profile goes to a train, the planner places the journey's nominal run
(:mod:`trackdb.headway`) beside those of the other trains on the line and looks for a conflict.
In ``adjust`` mode a conflicting journey is delayed, in steps, by the least delay that clears it
(every timing point's times later: the first leg runs longer and the later legs keep their
times); in ``check`` mode it is refused. Either way a journey that cannot be cleared within the
longest delay is refused (:class:`JourneyConflictError`, 409 over REST), naming the conflict.

Journeys are planned against journeys: the other trains are those alive on the same line
running a journey this planner booked (:meth:`JourneyPlanner.book`), each placed by the time
its own reports say has passed since it accepted it. The elapsed times come from each train's
own clock, so onboards whose clocks differ (a process each) plan together; the error is at most
one report interval.

A train without such a journey (none yet, or one sent before the planner knew it) is not
planned against: it would stand in the way for good, and a journey round a ring would then
be refused because another train waits for its own journey to be sent. The RBC's moving block
keeps every train apart from it, as it keeps a train running late: the plans, not the trains'
progress, are compared.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, replace

from protocol import messages as m
from trackdb.headway import (
    Conflict,
    HeadwayRule,
    NominalRun,
    PlacedRun,
    PlanningMode,
    delayed_journey,
    earliest_delay,
    first_conflict,
    nominal_run,
    planned_stops,
)
from trackdb.journey import Journey, JourneyCheck
from trackside.bridge import VehicleSnapshot
from trackside.errors import ConflictError

__all__ = [
    "DEFAULT_TRAIN_LENGTH_M",
    "Booking",
    "JourneyConflictError",
    "JourneyPlanner",
    "PlannedJourney",
    "PlannerStats",
    "PlanningMode",
]

DEFAULT_TRAIN_LENGTH_M = 6.0
"""A train whose session gave no length is planned as long as the URV [m]."""


class JourneyConflictError(ConflictError):
    """The journey's plan conflicts with another train's, and no allowed delay clears it."""


@dataclass(frozen=True, slots=True)
class PlannedJourney:
    journey: Journey
    """The journey to send: delayed by ``delay_s``."""
    delay_s: float
    conflict: Conflict | None
    """The conflict the undelayed journey had, ``None`` if none."""


@dataclass(slots=True)
class PlannerStats:
    """What the planner did with the journeys it was given, since the service started."""

    as_stored: int = 0
    delayed: int = 0
    refused: int = 0
    delay_s: float = 0.0
    """The delays given, summed [s]."""


@dataclass(frozen=True, slots=True)
class Booking:
    """A journey a train accepted, as the planner places it."""

    journey_id: str
    line_id: str
    start_m: float
    run: NominalRun
    accepted_sim_s: float
    """The train's own simulated time when it accepted the journey [s]."""
    top_speed_mps: float


class JourneyPlanner:
    """Plans each journey against the other trains' on its line; thread-safe."""

    def __init__(
        self,
        rule: HeadwayRule,
        *,
        mode: PlanningMode,
        fleet: Callable[[], list[VehicleSnapshot]],
        lengths: Callable[[str], float | None],
        ring_length_m: Callable[[str], float | None],
        max_delay_s: float = 600.0,
        step_s: float = 5.0,
    ) -> None:
        self.rule = rule
        self.mode = mode
        self.max_delay_s = max_delay_s
        self.step_s = step_s
        self._fleet = fleet
        self._lengths = lengths
        self._ring_length_m = ring_length_m
        self._booked: dict[str, Booking] = {}
        self._lock = threading.Lock()
        self._stats = PlannerStats()
        self._line_top_mps: dict[str, float] = {}
        self.sending = threading.RLock()
        """Held by a sender from the planning to the booking, so that two journeys are not
        planned at once, each blind to the other (``trackside.services.commands``)."""

    @property
    def stats(self) -> PlannerStats:
        """A copy of the counts (``/metrics``)."""
        with self._lock:
            return replace(self._stats)

    def plan(
        self,
        vehicle_id: str,
        journey: Journey,
        check: JourneyCheck,
        line_top_speed_mps: float | None = None,
    ) -> PlannedJourney:
        """The journey as it may be sent to ``vehicle_id``, delayed if need be;
        ``line_top_speed_mps`` the line's highest speed limit, for a journey without a cap.

        Raises
        ------
        JourneyConflictError
            The journey conflicts (``check`` mode), or no delay up to ``max_delay_s`` clears it.
        """
        if line_top_speed_mps is not None:
            with self._lock:
                self._line_top_mps[journey.line_id] = line_top_speed_mps
        try:
            planned = self._plan(vehicle_id, journey, check)
        except JourneyConflictError:
            with self._lock:
                self._stats.refused += 1
            raise
        with self._lock:
            if planned.delay_s > 0.0:
                self._stats.delayed += 1
                self._stats.delay_s += planned.delay_s
            else:
                self._stats.as_stored += 1
        return planned

    def _plan(self, vehicle_id: str, journey: Journey, check: JourneyCheck) -> PlannedJourney:
        if self.mode is PlanningMode.OFF:
            return PlannedJourney(journey, 0.0, None)
        others = self._others(vehicle_id, journey.line_id)
        ring = self._ring_length_m(journey.line_id)
        length = self._length(vehicle_id)

        def placed(delay_s: float) -> PlacedRun:
            delayed = delayed_journey(journey, delay_s)
            run = nominal_run(planned_stops(delayed, check.distances_m))
            return PlacedRun(
                vehicle_id,
                journey.start_position_m,
                length,
                run,
                top_speed_mps=self._top(journey, run),
            )

        if self.mode is PlanningMode.CHECK:
            conflict = first_conflict(placed(0.0), others, self.rule, ring_length_m=ring)
            if conflict is not None:
                raise JourneyConflictError(f"journey {journey.id} conflicts: {conflict}")
            return PlannedJourney(journey, 0.0, None)
        delay, conflict = earliest_delay(
            placed,
            others,
            self.rule,
            ring_length_m=ring,
            max_delay_s=self.max_delay_s,
            step_s=self.step_s,
        )
        if delay is None:
            raise JourneyConflictError(
                f"journey {journey.id} conflicts even {self.max_delay_s:g} s later: {conflict}"
            )
        return PlannedJourney(delayed_journey(journey, delay), delay, conflict)

    def book(self, vehicle_id: str, journey: Journey, check: JourneyCheck) -> None:
        """Record the journey ``vehicle_id`` accepted, at its latest report's time."""
        status = self._status(vehicle_id)
        if status is None:
            return
        run = nominal_run(planned_stops(journey, check.distances_m))
        booked = Booking(
            journey_id=journey.id,
            line_id=journey.line_id,
            start_m=journey.start_position_m,
            run=run,
            accepted_sim_s=status.sim_time_s,
            top_speed_mps=self._top(journey, run),
        )
        with self._lock:
            self._booked[vehicle_id] = booked

    def forget(self, vehicle_id: str) -> Booking | None:
        """Drop the vehicle's booking, a new journey being on its way to it; the booking
        dropped, for :meth:`restore` should the vehicle keep its journey."""
        with self._lock:
            return self._booked.pop(vehicle_id, None)

    def restore(self, vehicle_id: str, booking: Booking | None) -> None:
        """Book again what :meth:`forget` dropped: the vehicle rejected the new journey or
        never had it, and runs the one it had (unless it has been booked anew since)."""
        if booking is None:
            return
        with self._lock:
            self._booked.setdefault(vehicle_id, booking)

    def _top(self, journey: Journey, run: NominalRun) -> float:
        """The journey's cap, else its line's highest limit, else its nominal run's top [m/s]."""
        if journey.max_speed_mps is not None:
            return journey.max_speed_mps
        with self._lock:
            line_top = self._line_top_mps.get(journey.line_id)
        return float(run.speed_mps.max(initial=0.0)) if line_top is None else line_top

    def _status(self, vehicle_id: str) -> m.StatusReport | None:
        for snapshot in self._fleet():
            if snapshot.id == vehicle_id:
                return snapshot.status
        return None

    def _length(self, vehicle_id: str) -> float:
        length = self._lengths(vehicle_id)
        return DEFAULT_TRAIN_LENGTH_M if length is None else length

    def _others(self, vehicle_id: str, line_id: str) -> list[PlacedRun]:
        with self._lock:
            booked = dict(self._booked)
        others = []
        for snapshot in self._fleet():
            status = snapshot.status
            if snapshot.id == vehicle_id or status is None or status.line_id != line_id:
                continue
            entry = booked.get(snapshot.id)
            if entry is None or (entry.journey_id, entry.line_id) != (status.journey_id, line_id):
                continue  # no journey of the planner's: the moving block alone
            elapsed = status.sim_time_s - entry.accepted_sim_s
            length = self._length(snapshot.id)
            others.append(
                PlacedRun(
                    snapshot.id,
                    entry.start_m,
                    length,
                    entry.run,
                    started_s=-elapsed,
                    top_speed_mps=entry.top_speed_mps,
                )
            )
        return others
