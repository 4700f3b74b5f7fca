"""Leg replanning: a new current leg from the measured state, when the plan must change.

The ADF drives the journey's ODP (``onboard.adf.function``). This module redoes the current leg
from the train's measured position and speed, under the ETCS limits it keeps, when:

- the EoA falls short of the next stop (the train stops before it, and closes up from
  standstill), moves while the plan stops for it, or lies beyond the next stop again
  (:meth:`LegReplanner.follow_authority`, docs/decisions.md "Closing up to an EoA");
- the train has fallen :data:`BEHIND_PLAN_M` behind its reference (:meth:`~LegReplanner.catch_up`);
- a TSR is put in force or revoked (:meth:`~LegReplanner.under_new_limits`), and each later
  leg of the journey, planned under the old limits, as it begins
  (:meth:`~LegReplanner.renew_stale_leg`);
- the ETCS permitted speed that capped the leg when it was planned has risen
  (:meth:`~LegReplanner.released`);
- a stop is skipped, a train hold released, a fallback cancelled
  (:meth:`~LegReplanner.to_next_stop`);
- the trackside is lost while engaged (:meth:`~LegReplanner.fallback_stop`).

A leg replanned to the journey's next stop keeps the journey's later legs, delayed when it
arrives too late for the stop's dwell (the delayed departure is the journey progress's). Each
of these returns the new plan, or None when the current one stays; the driving function gives
it to the AD controller.
"""

from __future__ import annotations

import math

from onboard.adf.journey import JourneyStop
from onboard.adf.odp import InfeasibleLegError, OdpLeg, OdpPlan
from onboard.adf.odp_energy import (
    LIMIT_BRAKING_MPS2,
    MAX_BRAKING_MPS2,
    MRSP_MARGIN_MPS,
    replan_from_state,
)
from onboard.adf.progress import STANDSTILL_MPS, STOP_TOLERANCE_M, JourneyProgress
from onboard.plant.point_mass import PointMassParameters
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap

__all__ = ["LegReplanner"]

EOA_STOP_MARGIN_M = 5.0
"""Once it has closed up, the train stands this far before the end of its authority, on its
estimate [m]: a margin on the estimate's error against the truth (within 3.5 m on the
library's runs), so that it stands 1.5–8.5 m short of the EoA, never more than 10 m
(docs/decisions.md, "Closing up to an EoA")."""
EOA_MOVED_M = 5.0
"""A plan stopping for the EoA is redone when the EoA moves on by more than this (or closer)."""
ODOMETRY_SHARE = 0.06
"""The SvL seen from the max-safe front end comes closer as the odometry interval grows with the
distance run (3 % for the URV's odometer, docs/etcs.md; SUBSET-041 allows 5 %): the plan
anticipates it, with a margin, on the distance still to run to the EoA; the anticipation shrinks
as the train closes up."""
CLOSE_UP_M = 3.0
"""Standing at its stop for the EoA, the train closes up (a replan) when the stop can come at
least this much closer [m]."""
AUTHORITY_BRAKING_MPS2 = 0.35
"""The plan's braking for an EoA stop: half the service brake deceleration, so that the plan
stays under the ETCS permitted curve, whose SBD uses the full A_brake_service but starts the
reaction and build-up times earlier (a stop for the EoA is not a stop planned at the timetable's
pace: it comes when the MA is shortened, and must never bring an ETCS intervention)."""
AUTHORITY_LOOKAHEAD_S = 10.0
"""An EoA short of the next stop is planned for once the train could come within this long [s]
of the plan's braking for it (running at the highest of its speed, the journey's cap and the
MRSP up to it), not before: the journey's plan runs on until then, and an MA extended in the
meantime (the RBC's, section by section) costs nothing. A stop planned for at once held the cap
where the journey's plan coasted, and the replan back on time braked (bologna-ring's last leg
drew 0.369 kWh of plan against 0.275, docs/scenarios.md "The energy certificate")."""
TSR_DELAYS_S = (15.0, 30.0, 60.0, 120.0, 300.0)
"""How late [s] a leg replanned under a new TSR may arrive, tried in turn when it cannot keep
its schedule."""
BEHIND_PLAN_M = 25.0
"""A train this far behind its reference [m] (held back by a permitted speed that rose later
than planned, a brake that gave less, a fallback law) has its leg replanned from where it is:
the time-based reference would otherwise reach the stop, and leave it, before the train."""
RELEASED_MPS = 2.0 * MPS_PER_KMH
"""A leg planned under ETCS's permitted speed where that was below the journey's cap (a TSR
the train's rear is still inside, a braking curve, staff responsible) is capped at it over its
whole length: it is replanned once the permitted speed has risen this much above that cap
[m/s]. Issue 18, gen-1-430: the leg from east, replanned inside a 20 km/h TSR, ran the 4 km
to north at 19.5 km/h and missed the stop."""
BEHIND_RETRY_S = 5.0
"""After a catch-up replan that could not be made, the next try comes this much later [s]."""


class LegReplanner:
    """The current leg redone from the measured state, under the ETCS limits [m, s, m/s]."""

    def __init__(
        self, track_map: TrackMap, model: PointMassParameters, progress: JourneyProgress
    ) -> None:
        self.track_map = track_map
        self.model = model
        self.progress = progress
        self.permitted_speed_mps = math.inf
        self.eoa_at_m: float | None = None
        """The EoA in the plant's distance travelled [m]."""
        self.fallback_active = False
        """Running to the next stop for the unattended fallback: no other replan."""
        self.eoa_stop_m: float | None = None
        """Where the current plan stops for the EoA [m from the origin], when it does."""
        self._eoa_planned_for_m: float | None = None
        """The EoA [m from the origin] the stop at ``eoa_stop_m`` was planned for."""
        self._catch_up_after_s = -math.inf
        self._held_at_mps: float | None = None
        """The cap [m/s] of the plan in force when ETCS's permitted speed set it (below the
        journey's cap), else None."""
        self._stale_stops: set[str] = set()
        """The stops whose legs were planned before the MRSP last changed (a TSR put in force
        or revoked): each is replanned under the limits in force as it becomes the next stop."""

    def start(self) -> None:
        """A new journey: on its plan, no fallback, no stop for the EoA."""
        self.fallback_active = False
        self.eoa_stop_m = None
        self._stale_stops = set()
        self._held_at_mps = None

    def set_etcs_limits(
        self, permitted_speed_mps: float, eoa_ahead_m: float | None, *, position_m: float
    ) -> None:
        """The ETCS permitted speed [m/s], and the distance [m] to the EoA (if any) from
        ``position_m``, the position ETCS measured it from."""
        self.permitted_speed_mps = permitted_speed_mps
        self.eoa_at_m = None if eoa_ahead_m is None else position_m + eoa_ahead_m

    # -- on request ----------------------------------------------------------------------------

    def fallback_stop(self, now_s: float, *, position_m: float, speed_mps: float) -> OdpPlan | None:
        """A plan to stop at the next stop of the journey (the unattended fallback), None when
        the current one stops there already, or short of it for the EoA."""
        journey = self.progress.journey
        assert journey is not None
        stop = self.progress.next_stop(position_m)
        if stop is None:
            return None
        if self.eoa_stop_m is not None:
            # Already stopping short of it for the EoA (follow_authority is off in fallback).
            self.fallback_active = True
            return None
        travelled = self.progress.travelled_m(position_m)
        cap = journey.plan.cap_mps or self.track_map.mrsp_mps(journey.start_chainage_m)
        try:
            plan = replan_from_state(
                self.track_map,
                self.model,
                now_s=self.progress.journey_time_s(now_s),
                start_chainage_m=journey.start_chainage_m,
                distance_m=travelled,
                speed_mps=speed_mps,
                stop_distance_m=stop.distance_m - travelled,
                cruise_mps=max(cap, speed_mps),
            )
        except InfeasibleLegError:
            return None  # too close to stop on the plan: the current reference stops there anyway
        self.fallback_active = True
        self._held_at_mps = None
        return plan

    def to_next_stop(self, now_s: float, *, position_m: float, speed_mps: float) -> OdpPlan | None:
        """The current leg to the next stop (not skipped), on its schedule if it can be."""
        stop = self.progress.next_stop(position_m)
        if stop is None or self.fallback_active:
            return None
        self.eoa_stop_m = None
        travelled = self.progress.travelled_m(position_m)
        return self.replan(now_s, travelled, speed_mps, stop.distance_m, arrival_s=stop.arrival_s)

    def under_new_limits(
        self, now_s: float, *, position_m: float, speed_mps: float
    ) -> OdpPlan | None:
        """The current leg under a changed MRSP (a TSR put in force or revoked), on its schedule
        if it can be, else up to :data:`TSR_DELAYS_S` late. In the unattended fallback, the
        fallback's stop (the next stop, or the one short of it for the EoA) under the new
        limits: ETCS supervises them all the same (docs/decisions.md, "Issue 18")."""
        if self.progress.journey is None:
            return None
        stop = self.progress.next_stop(position_m)
        if stop is None:
            return None
        if not self.fallback_active:
            self.eoa_stop_m = None
            # The journey's later legs were planned under the old limits: each is redone as it
            # begins (:meth:`renew_stale_leg`). A TSR on the ring is met again a lap on.
            journey = self.progress.journey
            self._stale_stops = {
                later.timing_point_id
                for later in journey.stops
                if later.distance_m > stop.distance_m
            }
        return self._current_leg(now_s, self.progress.travelled_m(position_m), speed_mps, stop)

    def released(self, now_s: float, position_m: float, speed_mps: float) -> OdpPlan | None:
        """The current leg replanned, once, when ETCS's permitted speed capped it and has risen
        :data:`RELEASED_MPS` above that cap since (the train's rear has left a TSR); None
        otherwise."""
        held = self._held_at_mps
        if held is None or self.progress.journey is None:
            return None
        if self.permitted_speed_mps - MRSP_MARGIN_MPS < held + RELEASED_MPS:
            return None
        self._held_at_mps = None
        stop = self.progress.next_stop(position_m)
        if stop is None:
            return None
        return self._current_leg(now_s, self.progress.travelled_m(position_m), speed_mps, stop)

    def _current_leg(
        self, now_s: float, travelled_m: float, speed_mps: float, stop: JourneyStop
    ) -> OdpPlan | None:
        """The current leg under the limits in force: to the stop for the EoA when there is
        one, the fallback's stop as soon as it can be, else the next stop on schedule or
        later."""
        if self.eoa_stop_m is not None:
            return self.replan(now_s, travelled_m, speed_mps, self.eoa_stop_m, arrival_s=None)
        if self.fallback_active:
            return self.replan(
                now_s,
                travelled_m,
                speed_mps,
                stop.distance_m,
                arrival_s=None,
                braking_mps2=MAX_BRAKING_MPS2,
            )
        return self._on_schedule_or_later(now_s, travelled_m, speed_mps, stop)

    def renew_stale_leg(self, now_s: float, position_m: float, speed_mps: float) -> OdpPlan | None:
        """The leg to the next stop replanned under the limits in force, once, when it was
        planned before they changed (:meth:`under_new_limits`); None otherwise."""
        if self.fallback_active or not self._stale_stops:
            return None
        stop = self.progress.next_stop(position_m)
        if stop is None or stop.timing_point_id not in self._stale_stops:
            return None
        self._stale_stops.discard(stop.timing_point_id)
        if self.eoa_stop_m is not None:
            return None  # stopping for the EoA: its replan reads the limits in force
        travelled = self.progress.travelled_m(position_m)
        return self._on_schedule_or_later(now_s, travelled, speed_mps, stop)

    def _on_schedule_or_later(
        self, now_s: float, travelled_m: float, speed_mps: float, stop: JourneyStop
    ) -> OdpPlan | None:
        """The current leg on its schedule if it can be, else up to :data:`TSR_DELAYS_S`
        late."""
        for delay_s in (0.0, *TSR_DELAYS_S):
            plan = self.replan(
                now_s, travelled_m, speed_mps, stop.distance_m, arrival_s=stop.arrival_s + delay_s
            )
            if plan is not None:
                return plan
        return None

    # -- every control step --------------------------------------------------------------------

    def follow_authority(self, now_s: float, position_m: float, speed_mps: float) -> OdpPlan | None:
        """Replan when the EoA falls short of the next stop (stop before it), moves while the
        plan stops for it, or comes to lie beyond the next stop again (back on the journey, on
        time if the schedule still allows)."""
        if self.progress.journey is None or self.fallback_active:
            return None
        stop = self.progress.next_stop(position_m)
        eoa = None if self.eoa_at_m is None else self.eoa_at_m - self.progress.origin_m
        travelled = self.progress.travelled_m(position_m)
        if stop is None:
            return None
        if eoa is not None and eoa - EOA_STOP_MARGIN_M < stop.distance_m - STOP_TOLERANCE_M:
            target = eoa - EOA_STOP_MARGIN_M - ODOMETRY_SHARE * max(eoa - travelled, 0.0)
            if self.eoa_stop_m is None and target - travelled > _authority_reach_m(
                self.track_map, self.progress, position_m, travelled, speed_mps, target
            ):
                return None  # not yet within reach: the plan in force runs on
            known, planned_for = self.eoa_stop_m, self._eoa_planned_for_m
            # Hold the plan unless the stop must come closer, the EoA itself moved on, or the
            # train stands at the stop and can close up by a step: the anticipated growth of
            # the interval has shrunk with the distance left. Closing up while running, replan
            # after replan, brought the reference onto ETCS's permitted curve at low speed,
            # where the curve's reaction times dominate (docs/decisions.md).
            if known is not None and planned_for is not None and eoa <= planned_for + EOA_MOVED_M:
                standing = speed_mps <= STANDSTILL_MPS
                if known - 0.5 <= target and not (standing and target >= known + CLOSE_UP_M):
                    return None
            if target - travelled < STOP_TOLERANCE_M:
                return None  # at it already: the current plan holds the train
            plan = self.replan(now_s, travelled, speed_mps, target, arrival_s=None)
            self.eoa_stop_m, self._eoa_planned_for_m = target, eoa
            return plan
        if self.eoa_stop_m is not None:
            plan = self.replan(
                now_s, travelled, speed_mps, stop.distance_m, arrival_s=stop.arrival_s
            )
            self.eoa_stop_m = None
            return plan
        return None

    def catch_up(
        self, plan: OdpPlan, now_s: float, position_m: float, speed_mps: float
    ) -> OdpPlan | None:
        """Replan the leg from the measured state when the train has fallen
        :data:`BEHIND_PLAN_M` behind the reference of ``plan`` (the one followed) and nothing
        but the plan holds it back (the ETCS permitted speed at the MRSP or above)."""
        if self.progress.journey is None or self.fallback_active or now_s < self._catch_up_after_s:
            return None
        travelled = self.progress.travelled_m(position_m)
        reference_m = float(plan.reference(self.progress.journey_time_s(now_s))[0])
        if reference_m - travelled < BEHIND_PLAN_M:
            return None
        mrsp = self.track_map.mrsp_mps(self.track_map.normalise(position_m))
        stop = self.progress.next_stop(position_m)
        if stop is None or self.permitted_speed_mps < mrsp:
            return None
        if self.eoa_stop_m is not None:
            replanned = self.replan(now_s, travelled, speed_mps, self.eoa_stop_m, arrival_s=None)
        else:
            replanned = self.replan(
                now_s, travelled, speed_mps, stop.distance_m, arrival_s=stop.arrival_s
            )
        if replanned is None:
            self._catch_up_after_s = now_s + BEHIND_RETRY_S
        return replanned

    # -- the replan ----------------------------------------------------------------------------

    def replan(
        self,
        now_s: float,
        travelled_m: float,
        speed_mps: float,
        stop_m: float,
        *,
        arrival_s: float | None,
        braking_mps2: float | None = None,
    ) -> OdpPlan | None:
        """A new current leg from the measured state; the journey's later legs kept when the
        leg ends at the journey's next stop (``arrival_s`` given). None when the stop is too
        close to change: the ceilings and ETCS still hold the train back."""
        journey = self.progress.journey
        assert journey is not None
        plan = journey.plan
        cap = plan.cap_mps or self.track_map.mrsp_mps(journey.start_chainage_m)
        # Under the ETCS permitted speed by the plan's margin, as under the MRSP: a reference
        # on the NMPC's ceiling makes the NLP degenerate. It caps the whole leg, until it rises
        # (:meth:`released`).
        held = self.permitted_speed_mps - MRSP_MARGIN_MPS < cap
        cap = min(cap, self.permitted_speed_mps - MRSP_MARGIN_MPS)
        depart_s = _departure_s(self.progress, now_s, travelled_m, speed_mps)
        braking = braking_mps2 or (
            AUTHORITY_BRAKING_MPS2 if arrival_s is None else MAX_BRAKING_MPS2
        )
        # Into a lower limit under the ETCS curve of the speed decrease when the train can still
        # brake that gently (a TSR put in force just ahead), else at the stop's rate.
        limit_rates: tuple[float | None, ...] = (LIMIT_BRAKING_MPS2, None)
        for limit_braking in limit_rates:
            try:
                replanned = replan_from_state(
                    self.track_map,
                    self.model,
                    now_s=depart_s,
                    start_chainage_m=journey.start_chainage_m,
                    distance_m=travelled_m,
                    speed_mps=speed_mps,
                    stop_distance_m=stop_m - travelled_m,
                    cruise_mps=max(cap, speed_mps),
                    arrival_s=arrival_s,
                    braking_mps2=braking,
                    limit_braking_mps2=limit_braking,
                )
                break
            except InfeasibleLegError:
                continue
        else:
            return None
        self._held_at_mps = max(cap, speed_mps) if held else None
        legs = list(replanned.legs)
        if arrival_s is not None:
            legs += _later_legs(self.progress, plan, stop_m, arrival_end_s=legs[-1].end_s)
        return OdpPlan(
            [OdpLeg(leg.start_s, leg.start_distance_m, leg.segment) for leg in legs],
            start_chainage_m=plan.start_chainage_m,
            track_map=self.track_map,
            cap_mps=plan.cap_mps,
        )


def _departure_s(
    progress: JourneyProgress, now_s: float, travelled_m: float, speed_mps: float
) -> float:
    """When a leg replanned at ``now_s`` leaves [s from the journey's start]: now, or, for
    a train standing at a stop before its departure (a TSR put in force as it arrived), at
    that departure: the stop keeps its dwell, during which the ATO-OB holds the train. A
    leg leaving at once ran its reference a dwell ahead of the train (gen-1-152)."""
    journey_s = progress.journey_time_s(now_s)
    standing = progress.stopped_at(progress.origin_m + travelled_m, speed_mps)
    if standing is None:
        return journey_s
    return max(journey_s, progress.departure_s(standing))


def _later_legs(
    progress: JourneyProgress, plan: OdpPlan, stop_m: float, *, arrival_end_s: float
) -> list[OdpLeg]:
    """The journey's legs after the stop at ``stop_m``; when the replanned leg arrives
    there at ``arrival_end_s``, too late for the scheduled departure, they are delayed so
    that the stop keeps its scheduled dwell (a reference that left before the train had
    arrived would run it through the stop)."""
    later = [leg for leg in plan.legs if leg.start_distance_m >= stop_m - STOP_TOLERANCE_M]
    stop = progress.stop_near(stop_m)
    if not later or stop is None:
        return later
    delay_s = arrival_end_s + (stop.departure_s - stop.arrival_s) - later[0].start_s
    if delay_s <= 0.0:
        progress.delay_departure(stop, None)
        return later
    progress.delay_departure(stop, later[0].start_s + delay_s)
    return [OdpLeg(leg.start_s + delay_s, leg.start_distance_m, leg.segment) for leg in later]


def _authority_reach_m(
    track_map: TrackMap,
    progress: JourneyProgress,
    position_m: float,
    travelled_m: float,
    speed_mps: float,
    target_m: float,
) -> float:
    """How far ahead [m] a stop for the EoA at ``target_m`` must be planned for now: the run of
    :data:`AUTHORITY_LOOKAHEAD_S` and the braking at :data:`AUTHORITY_BRAKING_MPS2` from the
    highest speed the train may reach before it."""
    sections = track_map.mrsp_window(
        track_map.normalise(position_m), max(target_m - travelled_m, 0.0)
    )
    fastest = max((section.speed_mps for section in sections), default=speed_mps)
    journey = progress.journey
    if journey is not None and journey.plan.cap_mps is not None:
        fastest = min(fastest, journey.plan.cap_mps)
    fastest = max(fastest, speed_mps)
    return fastest * AUTHORITY_LOOKAHEAD_S + fastest**2 / (2.0 * AUTHORITY_BRAKING_MPS2)
