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
[s]. Where the train is on its journey is ``onboard.adf.progress``'s; redoing the current leg
(for the EoA, a TSR, a skipped stop, a released hold, a train behind its plan, the fallback)
``onboard.adf.replanning``'s.
"""

from __future__ import annotations

from onboard._exceptions import AdfError
from onboard.adf.autonomous import AutonomousDriving
from onboard.adf.journey import JourneyPlan, JourneyStop
from onboard.adf.nmpc import NmpcConfig, NmpcController
from onboard.adf.odp import OdpPlan
from onboard.adf.odp_energy import MRSP_MARGIN_MPS
from onboard.adf.progress import JourneyProgress
from onboard.adf.rd_controller import RemoteDrivingController
from onboard.adf.replanning import LegReplanner
from onboard.adf.supervisor import ModeRequest, SupervisoryController
from onboard.plant.point_mass import PointMassParameters
from protocol.messages import ScState
from protocol.units import GRAVITY_MPS2
from trackdb import TrackMap

__all__ = ["DrivingFunction", "NoJourneyError"]


class NoJourneyError(AdfError, RuntimeError):
    """Autonomous driving asked for with no journey planned."""


class DrivingFunction:
    """SC + RD PID + NMPC/ODP: from requests and limits to a force demand [N].

    The journey's progress (origin, stops served, skipped, delayed departures) is
    :attr:`progress`'s; the current leg's replanning, with the ETCS limits and the fallback,
    :attr:`replanner`'s. This class holds the controllers and turns the requests into them.
    """

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
        self.autonomous: AutonomousDriving | None = None
        """The AD controller on the plan followed: the journey's, or a replanned one."""
        self.progress = JourneyProgress()
        self.replanner = LegReplanner(track_map, model, self.progress)
        self._last_force_n = 0.0
        self.replans = 0
        """How many times the current leg was replanned (the fallback stop not counted)."""
        self.hold = False
        """Train hold: stay at the stopping point reached next until released."""

    # -- state ---------------------------------------------------------------------------------

    @property
    def state(self) -> ScState:
        return self.sc.state

    @property
    def journey(self) -> JourneyPlan | None:
        """The journey being driven, once started."""
        return self.progress.journey

    @property
    def skipped(self) -> set[str]:
        """Timing points the driver asked to run through ("Skip Stopping Point")."""
        return self.progress.skipped

    @property
    def served(self) -> int:
        """How many stops of the journey have been served (stopped at, passed or skipped)."""
        return self.progress.served

    @property
    def fallback_active(self) -> bool:
        """Whether the train runs to its fallback stop (the trackside lost while engaged)."""
        return self.replanner.fallback_active

    @property
    def permitted_speed_mps(self) -> float:
        """The ETCS permitted speed [m/s], as last set."""
        return self.replanner.permitted_speed_mps

    @property
    def stopping_for_authority(self) -> bool:
        """Whether the current plan stops before the EoA, short of the journey's next stop."""
        return self.replanner.eoa_stop_m is not None

    def use_line(self, track_map: TrackMap) -> None:
        """New track data of the same line, taken at standstill with ATO not engaged: the
        journey planned on the old ones is dropped (its profile names their version)."""
        self.track_map = self.replanner.track_map = track_map
        self.progress.journey = None
        self.autonomous = None

    # -- requests ------------------------------------------------------------------------------

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
        self.progress.start(journey, now_s, position_m=position_m)
        self.autonomous = AutonomousDriving(journey.plan, self.model, self.nmpc)
        self.replanner.start()
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
        self.replanner.set_etcs_limits(permitted_speed_mps, eoa_ahead_m, position_m=position_m)

    def stop_at_next_stopping_point(
        self, now_s: float, *, position_m: float, speed_mps: float
    ) -> None:
        """Replan to stop at the next stop of the journey (the unattended fallback)."""
        if self.journey is None:
            raise NoJourneyError("no journey to stop on")
        plan = self.replanner.fallback_stop(now_s, position_m=position_m, speed_mps=speed_mps)
        if plan is not None:
            self.autonomous = AutonomousDriving(plan, self.model, self.nmpc)
            self.autonomous.set_permitted_speed(self.permitted_speed_mps)

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
        self.replanner.fallback_active = False
        self._leave_for_next_stop(now_s, position_m=position_m, speed_mps=speed_mps)

    def speed_limits_changed(self, now_s: float, *, position_m: float, speed_mps: float) -> None:
        """A TSR was put in force or revoked (the TrackMap's MRSP changed): the current leg is
        replanned under the new limits, on its schedule if it can be, else up to
        :data:`onboard.adf.replanning.TSR_DELAYS_S` late."""
        if self.autonomous is None:
            return
        self._drive(
            self.replanner.under_new_limits(now_s, position_m=position_m, speed_mps=speed_mps)
        )

    def _leave_for_next_stop(self, now_s: float, *, position_m: float, speed_mps: float) -> None:
        self._drive(self.replanner.to_next_stop(now_s, position_m=position_m, speed_mps=speed_mps))

    def _drive(self, plan: OdpPlan | None) -> None:
        """Follow a replanned ``plan`` (when there is one)."""
        if plan is not None:
            self.autonomous = AutonomousDriving(plan, self.model, self.nmpc)
            self.replans += 1

    # -- journey progress ----------------------------------------------------------------------

    def next_stop(self, position_m: float) -> JourneyStop | None:
        """The first stop of the journey not yet served (stopped at, or passed)."""
        return self.progress.next_stop(position_m)

    def arrival_estimates(self, now_s: float, position_m: float) -> list[tuple[JourneyStop, float]]:
        """For each stop not yet served: the stop and its estimated arrival [s from the journey's
        start], the schedule shifted by the current delay against the plan (never early: the
        plan keeps the schedule)."""
        if self.journey is None or self.autonomous is None:
            return []
        return self.progress.arrival_estimates(self.autonomous.plan, now_s, position_m)

    def overrun_m(self, stop: JourneyStop, position_m: float) -> float:
        """How far the front end at ``position_m`` stands past ``stop`` beyond its tolerance [m]
        (0 when within it or short of it)."""
        return self.progress.overrun_m(stop, position_m)

    def stopped_at(self, position_m: float, speed_mps: float) -> JourneyStop | None:
        """The stop of the journey the vehicle stands at, if any."""
        return self.progress.stopped_at(position_m, speed_mps)

    def departure_s(self, stop: JourneyStop) -> float:
        """When the plan leaves ``stop`` [s from the journey's start]: its scheduled departure,
        or later when the train arrived late and the stop keeps its dwell."""
        return self.progress.departure_s(stop)

    def journey_time_s(self, now_s: float) -> float:
        return self.progress.journey_time_s(now_s)

    def reference_speed_mps(self, now_s: float) -> float | None:
        """The reference the SC follows now [m/s]: the ODP's in AD, the RD target's in RD."""
        state = self.state
        if state in (ScState.AD, ScState.HRD2AD) and self.autonomous is not None:
            # The plan's speed is never below zero, but its interpolation may round under it.
            journey_s = self.progress.journey_time_s(now_s)
            return max(float(self.autonomous.plan.reference(journey_s)[1]), 0.0)
        if state in (ScState.RD, ScState.HAD2RD):
            return max(float(self.rd.reference_speed_mps), 0.0)
        return None

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
        self.progress.update_served(position_m, speed_mps)
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
            self._drive(self.replanner.renew_stale_leg(now_s, position_m, speed_mps))
            self._drive(self.replanner.released(now_s, position_m, speed_mps))
            self._drive(self.replanner.follow_authority(now_s, position_m, speed_mps))
            # Not while the ATO-OB cuts traction or brakes: it holds the train back.
            if traction_allowed and not service_brake and self.autonomous is not None:
                plan = self.autonomous.plan
                self._drive(self.replanner.catch_up(plan, now_s, position_m, speed_mps))
        if self.sc.needs_autonomous and self.autonomous is not None:
            self.autonomous.set_permitted_speed(self.permitted_speed_mps)
            u_ad = self.autonomous.force_n(
                self.progress.journey_time_s(now_s),
                distance_m=self.progress.travelled_m(position_m),
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
