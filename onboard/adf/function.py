"""The Autonomous Driving Function as the onboard node runs it (seed 000 §5).

It bundles the supervisory controller, the RD PID, the NMPC with the ODP of the current journey,
and turns the ATO-OB controller's requests and the ETCS limits into one force demand per control
step:

- ``remote(target)``: remote driving at the operator's target (hand-over from AD if engaged);
- ``start_journey(plan)`` then ``engage()``: autonomous driving on the journey's ODP, whose time
  and distance count from the start of the journey;
- ``disengage()``: the SC goes OFF and the vehicle is held by the brake;
- ``set_etcs_limits(permitted, eoa_ahead, position_m=...)``: the ETCS constraints, never
  exceeded: the RD target and the NMPC's ceilings are capped by the permitted speed, and AD
  replans to stop before the EoA when it falls short of the next stop;
- ``stop_at_next_stopping_point()``: the unattended fallback when the trackside is lost while
  engaged: the ODP is replanned from the current state to the next stop of the journey;
- ``step(...)``: the force demand, with the ATO-OB's traction cut-off and service brake applied
  last.

Positions are the plant's distance travelled [m] (on a ring it keeps growing), times the node's
[s].
"""

from __future__ import annotations

import math

from onboard._exceptions import AdfError
from onboard.adf.autonomous import AutonomousDriving
from onboard.adf.journey import JourneyPlan, JourneyStop
from onboard.adf.nmpc import NmpcConfig, NmpcController
from onboard.adf.odp import InfeasibleLegError, OdpLeg, OdpPlan
from onboard.adf.odp_energy import (
    LIMIT_BRAKING_MPS2,
    MAX_BRAKING_MPS2,
    MRSP_MARGIN_MPS,
    replan_from_state,
)
from onboard.adf.rd_controller import RemoteDrivingController
from onboard.adf.supervisor import ModeRequest, SupervisoryController
from onboard.plant.point_mass import PointMassParameters
from protocol.messages import ScState
from protocol.units import GRAVITY_MPS2
from trackdb import TrackMap

__all__ = ["DrivingFunction", "NoJourneyError"]

STOP_TOLERANCE_M = 1.0
"""Standing this close to a stopping point [m] is standing at it."""
STANDSTILL_MPS = 0.01
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
ARRIVAL_RESOLUTION_S = 1e-3
"""How closely the arrival estimates find the time of the reference at the vehicle [s]."""
AUTHORITY_BRAKING_MPS2 = 0.35
"""The plan's braking for an EoA stop: half the service brake deceleration, so that the plan
stays under the ETCS permitted curve, whose SBD uses the full A_brake_service but starts the
reaction and build-up times earlier (a stop for the EoA is not a stop planned at the timetable's
pace: it comes when the MA is shortened, and must never bring an ETCS intervention)."""
PASSED_M = 10.0
"""A stop this far behind the front end [m] is passed. Standing between the stop's tolerance and
this far past it is an overrun: the train has stopped there (it does not run back), and the
stack reports the overrun."""
TSR_DELAYS_S = (15.0, 30.0, 60.0, 120.0, 300.0)
"""How late [s] a leg replanned under a new TSR may arrive, tried in turn when it cannot keep
its schedule."""
DELAY_PROBE_M = 0.5
BEHIND_PLAN_M = 25.0
"""A train this far behind its reference [m] (held back by a permitted speed that rose later
than planned, a brake that gave less, a fallback law) has its leg replanned from where it is:
the time-based reference would otherwise reach the stop, and leave it, before the train."""
BEHIND_RETRY_S = 5.0
"""After a catch-up replan that could not be made, the next try comes this much later [s]."""


class NoJourneyError(AdfError, RuntimeError):
    """Autonomous driving asked for with no journey planned."""


class DrivingFunction:
    """SC + RD PID + NMPC/ODP: from requests and limits to a force demand [N]."""

    def __init__(
        self,
        track_map: TrackMap,
        model: PointMassParameters,
        *,
        nmpc_config: NmpcConfig | None = None,
    ) -> None:
        self.track_map = track_map
        self.model = model
        self.sc = SupervisoryController()
        self.rd = RemoteDrivingController(
            mass_kg=model.mass_kg,
            rolling_coefficient=model.davis_a_n / (model.mass_kg * GRAVITY_MPS2),
        )
        self.nmpc = NmpcController(model, nmpc_config)
        self.control_s = self.nmpc.config.step_s
        self.remote_target_mps: float | None = None
        self.journey: JourneyPlan | None = None
        self.autonomous: AutonomousDriving | None = None
        self.fallback_active = False
        self.permitted_speed_mps = math.inf
        self._eoa_at_m: float | None = None
        """The EoA in the plant's distance travelled [m]."""
        self._origin_m = 0.0
        self._origin_s = 0.0
        self._last_force_n = 0.0
        self._eoa_stop_m: float | None = None
        self._eoa_planned_for_m: float | None = None
        """The EoA [m from the origin] the stop at ``_eoa_stop_m`` was planned for."""
        self._catch_up_after_s = -math.inf
        self._departures_s: dict[str, float] = {}
        """Departures delayed by a late arrival, by timing point [s from the journey's start]."""
        self._served = 0
        """How many stops of the journey have been served (stopped at, or passed)."""
        """Where the current plan stops for the EoA (distance travelled), when it does."""
        self.replans = 0
        self.skipped: set[str] = set()
        """Timing points the driver asked to run through ("Skip Stopping Point")."""
        self.hold = False
        """Train hold: stay at the stopping point reached next until released."""

    # -- requests ------------------------------------------------------------------------------

    @property
    def state(self) -> ScState:
        return self.sc.state

    def remote(
        self, target_mps: float, now_s: float, *, speed_mps: float, gradient_permille: float
    ) -> None:
        """Remote driving at ``target_mps`` (taking over from AD without a step)."""
        self.remote_target_mps = target_mps
        if self.sc.state is ScState.OFF:
            self.rd.reset(speed_mps)
        elif self.sc.needs_autonomous:
            self.rd.align(
                self._last_force_n, speed_mps=speed_mps, gradient_permille=gradient_permille
            )
        self.sc.request(ModeRequest.REMOTE, now_s)

    def restart_remote(self, target_mps: float, now_s: float, *, speed_mps: float) -> None:
        """Remote driving again from the train's speed, after an emergency brake overrode the
        manoeuvre: the reference starts where the train is, the integral from zero."""
        self.remote_target_mps = target_mps
        self.rd.reset(speed_mps)
        self.sc.request(ModeRequest.REMOTE, now_s)

    def start_journey(self, journey: JourneyPlan, now_s: float, *, position_m: float) -> None:
        """Make ``journey`` the one to drive: its time and distance start here and now."""
        self.journey = journey
        self._origin_m, self._origin_s = position_m, now_s
        self.autonomous = AutonomousDriving(journey.plan, self.model, self.nmpc)
        self.fallback_active = False
        self._eoa_stop_m = None
        self._served = 0
        self._departures_s.clear()
        self.nmpc.reset()
        if self.skipped:
            self._leave_for_next_stop(now_s, position_m=position_m, speed_mps=0.0)

    def engage(self, now_s: float) -> None:
        """Autonomous driving on the journey (hand-over from RD if remote driving). The journey
        starts at standstill, as the ATO engagement conditions require (DOMAIN.md §2.1)."""
        if self.autonomous is None:
            raise NoJourneyError("no journey to drive")
        self.nmpc.reset()
        self.sc.request(ModeRequest.AUTONOMOUS, now_s)

    def disengage(self, now_s: float) -> None:
        """The SC goes OFF: the vehicle is held by the brake."""
        self.sc.request(ModeRequest.OFF, now_s)
        self.remote_target_mps = None

    def set_etcs_limits(
        self, permitted_speed_mps: float, eoa_ahead_m: float | None, *, position_m: float
    ) -> None:
        """The ETCS permitted speed [m/s], and the distance [m] to the EoA (if any) from
        ``position_m``, the position ETCS measured it from."""
        self.permitted_speed_mps = permitted_speed_mps
        self._eoa_at_m = None if eoa_ahead_m is None else position_m + eoa_ahead_m

    def stop_at_next_stopping_point(
        self, now_s: float, *, position_m: float, speed_mps: float
    ) -> None:
        """Replan to stop at the next stop of the journey (the unattended fallback)."""
        if self.journey is None:
            raise NoJourneyError("no journey to stop on")
        stop = self.next_stop(position_m)
        if stop is None:
            return
        if self._eoa_stop_m is not None:
            # Already stopping short of it for the EoA (_follow_authority is off in fallback).
            self.fallback_active = True
            return
        travelled = position_m - self._origin_m
        cap = self.journey.plan.cap_mps or self.track_map.mrsp_mps(self.journey.start_chainage_m)
        try:
            plan = replan_from_state(
                self.track_map,
                self.model,
                now_s=now_s - self._origin_s,
                start_chainage_m=self.journey.start_chainage_m,
                distance_m=travelled,
                speed_mps=speed_mps,
                stop_distance_m=stop.distance_m - travelled,
                cruise_mps=max(cap, speed_mps),
            )
        except InfeasibleLegError:
            return  # too close to stop on the plan: the current reference stops there anyway
        self.autonomous = AutonomousDriving(plan, self.model, self.nmpc)
        self.autonomous.set_permitted_speed(self.permitted_speed_mps)
        self.fallback_active = True

    @property
    def stopping_for_authority(self) -> bool:
        """Whether the current plan stops before the EoA, short of the journey's next stop."""
        return self._eoa_stop_m is not None

    @property
    def served(self) -> int:
        """How many stops of the journey have been served (stopped at, passed or skipped)."""
        return self._served

    def skip_stop(
        self, timing_point_id: str, now_s: float, *, position_m: float, speed_mps: float
    ) -> None:
        """Run through ``timing_point_id`` (checked by the caller: a stop ahead, not the last):
        the current leg is replanned to the next stop not skipped, on its schedule if it can."""
        self.skipped.add(timing_point_id)
        if self.journey is not None and self.autonomous is not None:
            self._leave_for_next_stop(now_s, position_m=position_m, speed_mps=speed_mps)

    def set_hold(self, hold: bool, now_s: float, *, position_m: float, speed_mps: float) -> None:
        """Train hold on or off. Released at a stop, the train leaves for the next one: the
        current leg is replanned from standstill, on the schedule if it still can be."""
        released = self.hold and not hold
        self.hold = hold
        if released and self.stopped_at(position_m, speed_mps) is not None:
            self.nmpc.reset()
            self._leave_for_next_stop(now_s, position_m=position_m, speed_mps=speed_mps)

    def resume_journey(self, now_s: float, *, position_m: float, speed_mps: float) -> None:
        """Back on the journey after a cancelled fallback stop: the current leg is replanned to
        the next stop, on its schedule if it still can be."""
        self.fallback_active = False
        self._leave_for_next_stop(now_s, position_m=position_m, speed_mps=speed_mps)

    def speed_limits_changed(self, now_s: float, *, position_m: float, speed_mps: float) -> None:
        """A TSR was put in force or revoked (the TrackMap's MRSP changed): the current leg is
        replanned under the new limits, on its schedule if it can be, else up to
        :data:`TSR_DELAYS_S` late."""
        if self.journey is None or self.autonomous is None or self.fallback_active:
            return
        stop = self.next_stop(position_m)
        if stop is None:
            return
        self._eoa_stop_m = None
        travelled = position_m - self._origin_m
        for delay_s in (0.0, *TSR_DELAYS_S):
            before = self.replans
            self._replan(
                now_s, travelled, speed_mps, stop.distance_m, arrival_s=stop.arrival_s + delay_s
            )
            if self.replans > before:
                return

    def _leave_for_next_stop(self, now_s: float, *, position_m: float, speed_mps: float) -> None:
        stop = self.next_stop(position_m)
        if stop is None or self.fallback_active:
            return
        self._eoa_stop_m = None
        self._replan(
            now_s, position_m - self._origin_m, speed_mps, stop.distance_m, arrival_s=stop.arrival_s
        )

    # -- journey progress ----------------------------------------------------------------------

    def next_stop(self, position_m: float) -> JourneyStop | None:
        """The first stop of the journey not yet served (stopped at, or passed)."""
        if self.journey is None:
            return None
        self._update_served(position_m, speed_mps=math.inf)
        return next(iter(self._stops_ahead()), None)

    def _stops_ahead(self) -> list[JourneyStop]:
        """The stops not yet served, the skipped ones left out."""
        assert self.journey is not None
        return [
            s for s in self.journey.stops[self._served :] if s.timing_point_id not in self.skipped
        ]

    def _update_served(self, position_m: float, speed_mps: float) -> None:
        if self.journey is None:
            return
        travelled = position_m - self._origin_m
        stops = self.journey.stops
        while self._served < len(stops):
            stop = stops[self._served]
            stopped = speed_mps <= STANDSTILL_MPS and _stands_at(stop, travelled)
            skipped = stop.timing_point_id in self.skipped and travelled > stop.distance_m
            if not (stopped or skipped or travelled > stop.distance_m + PASSED_M):
                return
            self._served += 1

    def arrival_estimates(self, now_s: float, position_m: float) -> list[tuple[JourneyStop, float]]:
        """For each stop not yet served: the stop and its estimated arrival [s from the journey's
        start], the schedule shifted by the current delay against the plan (never early: the
        plan keeps the schedule)."""
        if self.journey is None or self.autonomous is None:
            return []
        self._update_served(position_m, speed_mps=math.inf)
        plan = self.autonomous.plan
        journey_s = now_s - self._origin_s
        ahead = position_m - self._origin_m + DELAY_PROBE_M
        low, high = plan.legs[0].start_s, plan.end_s
        if plan.reference(high)[0] < ahead:
            reference_s = high
        else:
            while high - low > ARRIVAL_RESOLUTION_S:  # when the reference passes the vehicle
                middle = 0.5 * (low + high)
                low, high = (middle, high) if plan.reference(middle)[0] < ahead else (low, middle)
            reference_s = high
        delay = max(journey_s - reference_s, 0.0)
        return [(stop, max(stop.arrival_s + delay, journey_s)) for stop in self._stops_ahead()]

    def overrun_m(self, stop: JourneyStop, position_m: float) -> float:
        """How far the front end at ``position_m`` stands past ``stop`` beyond its tolerance [m]
        (0 when within it or short of it)."""
        past_m = position_m - self._origin_m - stop.distance_m
        return max(past_m - STOP_TOLERANCE_M, 0.0)

    def stopped_at(self, position_m: float, speed_mps: float) -> JourneyStop | None:
        """The stop of the journey the vehicle stands at, if any."""
        if self.journey is None or speed_mps > STANDSTILL_MPS:
            return None
        travelled = position_m - self._origin_m
        for stop in self.journey.stops:
            if stop.timing_point_id in self.skipped:
                continue
            if _stands_at(stop, travelled):
                return stop
        return None

    def reference_speed_mps(self, now_s: float) -> float | None:
        """The reference the SC follows now [m/s]: the ODP's in AD, the RD target's in RD."""
        state = self.state
        if state in (ScState.AD, ScState.HRD2AD) and self.autonomous is not None:
            # The plan's speed is never below zero, but its interpolation may round under it.
            return max(float(self.autonomous.plan.reference(now_s - self._origin_s)[1]), 0.0)
        if state in (ScState.RD, ScState.HAD2RD):
            return max(float(self.rd.reference_speed_mps), 0.0)
        return None

    def journey_time_s(self, now_s: float) -> float:
        return now_s - self._origin_s

    # -- replanning for the movement authority ------------------------------------------------

    def _follow_authority(self, now_s: float, position_m: float, speed_mps: float) -> None:
        """Replan when the EoA falls short of the next stop (stop before it), moves while the
        plan stops for it, or comes to lie beyond the next stop again (back on the journey, on
        time if the schedule still allows)."""
        if self.journey is None or self.fallback_active:
            return
        stop = self.next_stop(position_m)
        eoa = None if self._eoa_at_m is None else self._eoa_at_m - self._origin_m
        travelled = position_m - self._origin_m
        if stop is None:
            return
        if eoa is not None and eoa - EOA_STOP_MARGIN_M < stop.distance_m - STOP_TOLERANCE_M:
            target = eoa - EOA_STOP_MARGIN_M - ODOMETRY_SHARE * max(eoa - travelled, 0.0)
            known, planned_for = self._eoa_stop_m, self._eoa_planned_for_m
            # Hold the plan unless the stop must come closer, the EoA itself moved on, or the
            # train stands at the stop and can close up by a step: the anticipated growth of
            # the interval has shrunk with the distance left. Closing up while running, replan
            # after replan, brought the reference onto ETCS's permitted curve at low speed,
            # where the curve's reaction times dominate (docs/decisions.md).
            if known is not None and planned_for is not None and eoa <= planned_for + EOA_MOVED_M:
                standing = speed_mps <= STANDSTILL_MPS
                if known - 0.5 <= target and not (standing and target >= known + CLOSE_UP_M):
                    return
            if target - travelled < STOP_TOLERANCE_M:
                return  # at it already: the current plan holds the train
            self._replan(now_s, travelled, speed_mps, target, arrival_s=None)
            self._eoa_stop_m, self._eoa_planned_for_m = target, eoa
        elif self._eoa_stop_m is not None:
            self._replan(now_s, travelled, speed_mps, stop.distance_m, arrival_s=stop.arrival_s)
            self._eoa_stop_m = None

    def _replan(
        self,
        now_s: float,
        travelled_m: float,
        speed_mps: float,
        stop_m: float,
        *,
        arrival_s: float | None,
        braking_mps2: float | None = None,
    ) -> None:
        """A new current leg from the measured state; the journey's later legs kept when the
        leg ends at the journey's next stop."""
        assert self.journey is not None
        plan = self.journey.plan
        cap = plan.cap_mps or self.track_map.mrsp_mps(self.journey.start_chainage_m)
        # Under the ETCS permitted speed by the plan's margin, as under the MRSP: a reference
        # on the NMPC's ceiling makes the NLP degenerate.
        cap = min(cap, self.permitted_speed_mps - MRSP_MARGIN_MPS)
        journey_s = now_s - self._origin_s
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
                    now_s=journey_s,
                    start_chainage_m=self.journey.start_chainage_m,
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
            return  # too close to change: the ceilings and ETCS still hold the train back
        legs = list(replanned.legs)
        if arrival_s is not None:
            legs += self._later_legs(plan, stop_m, arrival_end_s=legs[-1].end_s)
        self.autonomous = AutonomousDriving(
            OdpPlan(
                [OdpLeg(leg.start_s, leg.start_distance_m, leg.segment) for leg in legs],
                start_chainage_m=plan.start_chainage_m,
                track_map=self.track_map,
                cap_mps=plan.cap_mps,
            ),
            self.model,
            self.nmpc,
        )
        self.replans += 1

    def _catch_up(self, now_s: float, position_m: float, speed_mps: float) -> None:
        """Replan the leg from the measured state when the train has fallen
        :data:`BEHIND_PLAN_M` behind its reference and nothing but the plan holds it back (the
        ETCS permitted speed at the MRSP or above)."""
        if (
            self.journey is None
            or self.autonomous is None
            or self.fallback_active
            or now_s < self._catch_up_after_s
        ):
            return
        travelled = position_m - self._origin_m
        reference_m = float(self.autonomous.plan.reference(now_s - self._origin_s)[0])
        if reference_m - travelled < BEHIND_PLAN_M:
            return
        mrsp = self.track_map.mrsp_mps(self.track_map.normalise(position_m))
        stop = self.next_stop(position_m)
        if stop is None or self.permitted_speed_mps < mrsp:
            return
        before = self.replans
        if self._eoa_stop_m is not None:
            self._replan(now_s, travelled, speed_mps, self._eoa_stop_m, arrival_s=None)
        else:
            self._replan(now_s, travelled, speed_mps, stop.distance_m, arrival_s=stop.arrival_s)
        if self.replans == before:
            self._catch_up_after_s = now_s + BEHIND_RETRY_S

    def _later_legs(self, plan: OdpPlan, stop_m: float, *, arrival_end_s: float) -> list[OdpLeg]:
        """The journey's legs after the stop at ``stop_m``; when the replanned leg arrives
        there at ``arrival_end_s``, too late for the scheduled departure, they are delayed so
        that the stop keeps its scheduled dwell (a reference that left before the train had
        arrived would run it through the stop)."""
        later = [leg for leg in plan.legs if leg.start_distance_m >= stop_m - STOP_TOLERANCE_M]
        assert self.journey is not None
        stop = next(
            (s for s in self.journey.stops if abs(s.distance_m - stop_m) <= STOP_TOLERANCE_M), None
        )
        if not later or stop is None:
            return later
        delay_s = arrival_end_s + (stop.departure_s - stop.arrival_s) - later[0].start_s
        if delay_s <= 0.0:
            self._departures_s.pop(stop.timing_point_id, None)
            return later
        self._departures_s[stop.timing_point_id] = later[0].start_s + delay_s
        return [OdpLeg(leg.start_s + delay_s, leg.start_distance_m, leg.segment) for leg in later]

    def departure_s(self, stop: JourneyStop) -> float:
        """When the plan leaves ``stop`` [s from the journey's start]: its scheduled departure,
        or later when the train arrived late and the stop keeps its dwell."""
        return self._departures_s.get(stop.timing_point_id, stop.departure_s)

    # -- control -------------------------------------------------------------------------------

    def step(
        self,
        now_s: float,
        *,
        position_m: float,
        speed_mps: float,
        applied_force_n: float,
        gradient_permille: float,
        force_limits_n: tuple[float, float],
        traction_allowed: bool = True,
        service_brake: bool = False,
    ) -> float:
        """The force demand [N] for the next control step."""
        self._update_served(position_m, speed_mps)
        u_rd = 0.0
        if self.sc.needs_remote:
            # Under the ceilings by the plans' margin: a target on the MRSP is overshot.
            mrsp = self.track_map.mrsp_mps(self.track_map.normalise(position_m))
            ceiling = min(self.permitted_speed_mps, mrsp)
            target = min(self.remote_target_mps or 0.0, ceiling - MRSP_MARGIN_MPS)
            u_rd = self.rd.step(
                self.control_s,
                target_speed_mps=max(target, 0.0),
                speed_mps=speed_mps,
                gradient_permille=gradient_permille,
                force_limits_n=force_limits_n,
            )
        u_ad = 0.0
        if self.sc.needs_autonomous:
            self._follow_authority(now_s, position_m, speed_mps)
            if traction_allowed and not service_brake:  # else the ATO-OB holds it back
                self._catch_up(now_s, position_m, speed_mps)
        if self.sc.needs_autonomous and self.autonomous is not None:
            self.autonomous.set_permitted_speed(self.permitted_speed_mps)
            u_ad = self.autonomous.force_n(
                now_s - self._origin_s,
                distance_m=position_m - self._origin_m,
                speed_mps=speed_mps,
                applied_force_n=applied_force_n,
            )
        force = self.sc.step(self.control_s, now_s, remote_force_n=u_rd, autonomous_force_n=u_ad)
        self.sc.acknowledge_replan()
        low, high = force_limits_n
        demand = low if force is None else min(max(force, low), high)
        if not traction_allowed:
            demand = min(demand, 0.0)
        if service_brake or (self.hold and self.stopped_at(position_m, speed_mps) is not None):
            demand = low
        self._last_force_n = demand
        return demand


def _stands_at(stop: JourneyStop, travelled_m: float) -> bool:
    """At ``travelled_m`` [m] from the journey's origin the front end stands at ``stop``: within
    its tolerance, or past it by less than :data:`PASSED_M` (an overrun)."""
    return -STOP_TOLERANCE_M <= travelled_m - stop.distance_m <= PASSED_M
