"""The journey profile on board: reviewed against the track data, planned from where the train
stands, and handed to the ADF when ATO is engaged.

A journey profile is accepted only if its ODP can be planned from where the vehicle stands: an
infeasible leg is a rejection with its reason. A journey planned at acceptance is planned again
at engagement if the vehicle moved more than :data:`REPLAN_MOVED_M` in between.

At acceptance the Energy Manager (``onboard.energy_manager``) reckons the plan against the
batteries and the range extender. When the margin is short, the journey is planned again with
each stop's arrival at the end of its window (T_ARRIVAL_WINDOW, the timing tolerance the
profile grants): the slower profile, kept when it needs less energy (event
``energy.slower_profile``). When even that leaves the margin short, the journey is accepted all
the same and the operator is warned before departure (event ``energy.insufficient``, and the
status report's ``energy.short``): he decides whether to engage (docs/energy.md).
"""

from __future__ import annotations

from onboard.adf.function import DrivingFunction
from onboard.adf.journey import JourneyPlan, JourneyStop, plan_journey
from onboard.adf.odp import InfeasibleLegError
from onboard.energy_manager import EnergyAssessment, EnergyManager
from onboard.events import StackEvent
from onboard.plant.point_mass import PointMassParameters
from onboard.track_database_manager import TrackDatabaseManager
from protocol import messages as m
from protocol.units import J_PER_KWH
from trackdb import TrackMap

__all__ = ["REPLAN_MOVED_M", "JourneyKeeper", "within_arrival_windows"]

REPLAN_MOVED_M = 1.0
"""A journey planned at acceptance is replanned at engagement if the vehicle moved more [m]."""


class JourneyKeeper:
    """The accepted journey's plan, and whether the ADF has started it."""

    def __init__(
        self,
        track_map: TrackMap,
        model: PointMassParameters,
        track_database: TrackDatabaseManager,
        driving: DrivingFunction,
        *,
        energy_plans: bool,
        energy: EnergyManager | None = None,
    ) -> None:
        self.track_map = track_map
        self.model = model
        self.track_database = track_database
        self.driving = driving
        self.energy_plans = energy_plans
        self.energy = energy
        self.plan: JourneyPlan | None = None
        self.started = False
        self.slowed_for_energy = False
        """The plan uses the arrival windows because the energy margin was short."""
        self.energy_short = False
        """Even so the margin was short at acceptance: the operator was warned."""
        self.events: list[StackEvent] = []
        self._planned_at_m = 0.0
        self._planned_profile: m.JourneyProfile | None = None
        self._short_while_running = False

    def use_line(self, track_map: TrackMap) -> None:
        """New track data: a journey accepted on the old ones is dropped, not started."""
        self.track_map = track_map
        self.plan, self.started = None, False
        self.slowed_for_energy = self.energy_short = False

    def review(self, profile: m.JourneyProfile, position_m: float) -> tuple[bool, str | None]:
        """Accept a journey profile (reviewed against the track data, then planned from
        ``position_m`` [m]) or reject it with the reason."""
        review = self.track_database.review(profile)
        if not review.accepted:
            return False, review.reason
        try:
            plan = self._plan(profile, position_m)
        except InfeasibleLegError as exc:
            self.track_database.journey = None
            return False, f"infeasible: {exc}"
        self.plan, self._planned_at_m, self._planned_profile = plan, position_m, profile
        self.slowed_for_energy = self.energy_short = False
        self._note_plan(plan)
        if self.energy is not None:
            self._within_energy(self.energy, plan, profile, position_m)
        self.started = False
        self.driving.skipped.clear()
        return True, None

    def start(self, now_s: float, position_m: float) -> None:
        """Hand the accepted journey to the ADF (once), replanned if the train moved."""
        journey = self.track_database.journey
        if self.started or self.plan is None or journey is None:
            return
        if abs(position_m - self._planned_at_m) > REPLAN_MOVED_M:
            self.plan = self._plan(self._planned_profile or journey, position_m)
        self.driving.start_journey(self.plan, now_s, position_m=position_m)
        self.started, self._short_while_running = True, False

    def stops_ahead(self, position_m: float) -> tuple[JourneyStop, ...] | None:
        """The stopping points still to serve (all of them before the start); None without
        an accepted journey."""
        driving = self.driving
        if driving.journey is not None:
            driving.next_stop(position_m)  # brings the served stops up to date
            return tuple(driving.journey.stops[driving.served :])
        if self.plan is not None:
            return tuple(self.plan.stops)
        return None

    def _within_energy(
        self,
        energy: EnergyManager,
        accepted: JourneyPlan,
        profile: m.JourneyProfile,
        position_m: float,
    ) -> None:
        """The Energy Manager's check of the ``accepted`` plan: the slower profile when the
        margin is short and that needs less, and the operator warned when it is short even so."""
        first = energy.assess(accepted.plan)
        if not first.short:
            return
        final, slower = first, within_arrival_windows(profile)
        if slower is not None:
            try:
                plan = self._plan(slower, position_m)
            except InfeasibleLegError:
                plan = None
            second = None if plan is None else energy.assess(plan.plan)
            if plan is not None and second is not None and _needs_less(second, first):
                self.plan, self._planned_profile, final = plan, slower, second
                self.slowed_for_energy = True
                self._note(
                    m.EventSeverity.INFO,
                    "energy.slower_profile",
                    f"energy margin short at the timetable's pace ({_kwh(first)}): planned "
                    f"with every arrival at the end of its window ({_kwh(second)})",
                )
        if final.short:
            self.energy_short = True
            self._note(
                m.EventSeverity.WARNING,
                "energy.insufficient",
                f"the batteries and the range extender cannot finish journey "
                f"{profile.journey_id} with the reserve ({_kwh(final)}): do not engage",
            )

    def watch_energy(self, now_s: float) -> None:
        """While the journey runs: warn the operator once when the margin on the plan followed
        turns short (event ``energy.margin_short``), a journey accepted short excepted."""
        driving, energy = self.driving, self.energy
        if energy is None or not self.started or self.energy_short or driving.autonomous is None:
            return
        reckoning = energy.assess(driving.autonomous.plan, driving.journey_time_s(now_s))
        if reckoning.short and not self._short_while_running:
            self._note(
                m.EventSeverity.WARNING,
                "energy.margin_short",
                f"the energy margin to the end of the journey has become short ({_kwh(reckoning)})",
            )
        self._short_while_running = reckoning.short

    def take_events(self) -> list[StackEvent]:
        """What the journey keeper noted for the event log since the last call."""
        events, self.events = self.events, []
        return events

    def _note(self, severity: m.EventSeverity, code: str, text: str) -> None:
        self.events.append(StackEvent(severity, code, text))

    def _note_plan(self, plan: JourneyPlan) -> None:
        """Each leg kept as the plain LSPB and each passing time not kept: a warning in the
        event log (docs/energy-planning.md)."""
        for fallback in plan.fallbacks:
            text = f"leg {fallback.leg + 1} keeps the plain LSPB: {fallback.reason}"
            self._note(m.EventSeverity.WARNING, "journey.energy_plan_fallback", text)
        for miss in plan.passing_missed:
            text = f"passing point {miss.timing_point_id} not kept: {miss.reason}"
            self._note(m.EventSeverity.WARNING, "journey.passing_time_missed", text)

    def _plan(self, profile: m.JourneyProfile, position_m: float) -> JourneyPlan:
        return plan_journey(
            self.track_map,
            self.model,
            profile,
            start_chainage_m=self.track_map.normalise(position_m),
            energy=self.energy_plans,
        )


def within_arrival_windows(profile: m.JourneyProfile) -> m.JourneyProfile | None:
    """The profile with each timing point's arrival at the end of its window (its
    ``arrival_tolerance_s``), departures kept where the dwell allows (never before the arrival
    plus the minimum dwell); None when no point grants a window."""
    if not any(point.arrival_tolerance_s > 0.0 for point in profile.timing_points):
        return None
    points = []
    for point in profile.timing_points:
        arrival = point.arrival_time_s + point.arrival_tolerance_s
        departure = point.departure_time_s
        if departure is not None:
            departure = max(departure, arrival + point.minimum_dwell_s)
        points.append(
            point.model_copy(
                update={
                    "arrival_time_s": arrival,
                    "arrival_tolerance_s": 0.0,
                    "departure_time_s": departure,
                }
            )
        )
    return profile.model_copy(update={"timing_points": tuple(points)})


def _needs_less(slower: EnergyAssessment, first: EnergyAssessment) -> bool:
    if slower.energy_to_go_j is None or first.energy_to_go_j is None:
        return False
    return slower.energy_to_go_j < first.energy_to_go_j


def _kwh(assessment: EnergyAssessment) -> str:
    """The reckoning in the operator's units: needed, available, margin [kWh]."""
    needed = assessment.energy_to_go_j or 0.0
    available = (assessment.battery_available_j or 0.0) + (
        assessment.range_extender_available_j or 0.0
    )
    return (
        f"{needed / J_PER_KWH:.2f} kWh needed, {available / J_PER_KWH:.2f} kWh available, "
        f"margin {(available - needed) / J_PER_KWH:+.2f} kWh"
    )
