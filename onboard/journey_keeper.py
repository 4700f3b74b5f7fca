"""The journey profile on board: reviewed against the track data, planned from where the train
stands, and handed to the ADF when ATO is engaged.

A journey profile is accepted only if its ODP can be planned from where the vehicle stands: an
infeasible leg is a rejection with its reason. A journey planned at acceptance is planned again
at engagement if the vehicle moved more than :data:`REPLAN_MOVED_M` in between.
"""

from __future__ import annotations

from onboard.adf.function import DrivingFunction
from onboard.adf.journey import JourneyPlan, JourneyStop, plan_journey
from onboard.adf.odp import InfeasibleLegError
from onboard.plant.point_mass import PointMassParameters
from onboard.track_database_manager import TrackDatabaseManager
from protocol import messages as m
from trackdb import TrackMap

__all__ = ["REPLAN_MOVED_M", "JourneyKeeper"]

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
    ) -> None:
        self.track_map = track_map
        self.model = model
        self.track_database = track_database
        self.driving = driving
        self.energy_plans = energy_plans
        self.plan: JourneyPlan | None = None
        self.started = False
        self._planned_at_m = 0.0

    def use_line(self, track_map: TrackMap) -> None:
        """New track data: a journey accepted on the old ones is dropped, not started."""
        self.track_map = track_map
        self.plan, self.started = None, False

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
        self.plan, self._planned_at_m = plan, position_m
        self.started = False
        self.driving.skipped.clear()
        return True, None

    def start(self, now_s: float, position_m: float) -> None:
        """Hand the accepted journey to the ADF (once), replanned if the train moved."""
        journey = self.track_database.journey
        if self.started or self.plan is None or journey is None:
            return
        if abs(position_m - self._planned_at_m) > REPLAN_MOVED_M:
            self.plan = self._plan(journey, position_m)
        self.driving.start_journey(self.plan, now_s, position_m=position_m)
        self.started = True

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

    def _plan(self, profile: m.JourneyProfile, position_m: float) -> JourneyPlan:
        return plan_journey(
            self.track_map,
            self.model,
            profile,
            start_chainage_m=self.track_map.normalise(position_m),
            energy=self.energy_plans,
        )
