"""The onboard stack of one vehicle without its transports: ETCS, ATO-OB controller, ADF.

The node (``onboard.node``) moves messages over Zenoh and runs the tasks; this class holds what
they act on, so that the whole chain can be driven in lockstep without a network:

- the emulated ETCS onboard supervises the train on its own odometry: the axle-end sensors'
  readings and the balise groups its BTM reads (every 100 ms);
- the ATO-OB controller decides, from ETCS, the journey, the track data and the session, whether
  ATO is available, ready or engaged, and what the ADF is asked to do (every 200 ms);
- the ADF (:class:`onboard.adf.function.DrivingFunction`) turns that into a force demand, under
  the ETCS permitted speed and EoA; ETCS's own brake commands act on the vehicle last.

Remote driving is the operator driving through the ADF's RD controller: it is possible whenever
ATO is not engaged (the ATO-OB's CO/NA/AV/RE), not only from NA, since on an unmanned vehicle the
remote driver is the only way to move it before ATO is available (the seed 000 field sequence
starts in SR under RD). A journey profile is accepted only if its ODP can be planned from where
the vehicle stands: an infeasible leg is a rejection with its reason.

The stack never reads the plant (ARCHITECTURE.md, the truth boundary): the ATO-OB and the ADF
see the train through the sensor-fusion estimate (:class:`Locator`), ETCS through its odometry,
the ADF's bumpless transfer through the drives' feedback (:class:`DriveReading`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from onboard.adf.function import DrivingFunction
from onboard.adf.journey import JourneyPlan, plan_journey
from onboard.adf.odp import InfeasibleLegError
from onboard.adf.supervisor import ModeRequest
from onboard.ato_ob import AtoObController, AtoObInputs, EtcsStatus, RequestRefusedError
from onboard.ato_ob.vital_link import VitalLink
from onboard.etcs import URV_ODOMETER, EtcsOnboard, MaSection, MovementAuthority
from onboard.plant.point_mass import PointMassParameters
from onboard.plant.readings import BaliseDetection, WheelReading
from onboard.track_database_manager import TrackDatabaseManager
from onboard.vc.installation import VcInstallation
from onboard.vc.ipc import VcEventKind
from protocol import messages as m
from protocol.units import MPS_PER_KMH
from trackdb import TemporarySpeedRestriction, TrackMap

__all__ = ["Locator", "OnboardStack", "StackEvent", "authority_from_extent"]

STANDSTILL_MPS = 0.01
MIN_AUTHORITY_M = 5.0
"""An MA shorter than this ahead does not allow leaving a platform."""
REPLAN_MOVED_M = 1.0
"""A journey planned at acceptance is replanned at engagement if the vehicle moved more."""
_ENGAGED = (m.AtoState.ENGAGED, m.AtoState.DISENGAGING)
_VC_ALARMS = frozenset(
    {VcEventKind.EB_CONDITION, VcEventKind.SYSTEM_DECAY, VcEventKind.EB_COMMANDED}
)


@dataclass(frozen=True)
class StackEvent:
    severity: m.EventSeverity
    code: str
    text: str


def authority_from_extent(extent: m.MovementAuthorityExtent) -> MovementAuthority:
    """The ETCS onboard's MA from the RBC's wire extent: distances from its start (packet 15)."""
    return MovementAuthority(
        reference_m=extent.start_m,
        end_of_authority_m=extent.length_m,
        danger_point_m=extent.danger_point_m,
        overlap_m=extent.overlap_m,
        overlap_timer_s=extent.overlap_timer_s,
        overlap_timer_start_m=extent.overlap_timer_start_m,
        release_speed_mps=extent.release_speed_mps,
        sections=tuple(
            MaSection(length_m=s.length_m, timer_s=s.timer_s, timer_stop_m=s.timer_stop_m)
            for s in extent.sections
        ),
    )


class Locator(Protocol):
    """Where the train is and how fast it goes, as the onboard's localisation estimates it."""

    @property
    def position_m(self) -> float:
        """The estimated front end [m], unwrapped on a ring."""

    @property
    def speed_mps(self) -> float: ...

    @property
    def acceleration_mps2(self) -> float: ...

    @property
    def localisation_valid(self) -> bool:
        """Good enough to drive on (the ATO-OB's "localised" condition)."""

    def fix(self, chainage_m: float, detected_s: float) -> None:
        """A balise group located at ``detected_s`` [s], at its chainage [m]."""


ForceLimits = Callable[[float], tuple[float, float]]
"""The vehicle's (min, max) force [N] at a speed [m/s]: its traction and braking data."""


@dataclass
class OnboardStack:
    """ETCS + ATO-OB controller + ADF for one vehicle."""

    track_map: TrackMap
    locator: Locator
    """The sensor-fusion localisation the ATO-OB and the ADF use."""
    model: PointMassParameters
    force_limits_n: ForceLimits
    start_position_m: float = 0.0
    """Where the vehicle was powered up [m] (its stored position): ETCS's odometry starts there,
    with the national location accuracy until the first balise group."""
    start_s: float = 0.0
    energy_plans: bool = True
    vital: VcInstallation | None = None
    """The Vital Control fitted to the vehicle, if any (its tasks run on the node)."""
    session_alive: bool = False
    internal_fault: bool = False
    """An ATO-OB internal fault (injected by scenario runs): the controller goes to FA."""
    events: list[StackEvent] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.track_database = TrackDatabaseManager(self.track_map)
        self.etcs = EtcsOnboard(
            self.track_map,
            position_m=self.start_position_m,
            start_s=self.start_s,
            odometer=URV_ODOMETER,
        )
        self.etcs.start_of_mission(self.start_s)
        self.controller = AtoObController(start_s=self.start_s)
        self.driving = DrivingFunction(self.track_map, self.model)
        self.journey_plan: JourneyPlan | None = None
        self._planned_at_m = 0.0
        self._journey_started = False
        self.remote_selected = False
        self.remote_target_mps: float | None = None
        self.force_demand_n = 0.0
        self._ad_requested = False
        self._overrun_noted: str | None = None
        self.vital_links = (
            [
                VitalLink(
                    request,
                    response,
                    vigilance_timeout_s=self.vital.config.vigilance_timeout_s,
                    sequence_modulo=self.vital.config.sequence_modulo,
                )
                for request, response in self.vital.links
            ]
            if self.vital is not None
            else []
        )
        self._balise_reading = self.etcs.last_balise_reading
        self._vc_events_seen = (0, 0)
        self._pair_events_seen = 0
        self._vc_braking = self.vital is not None and self.vital.eb_commanded

    # -- state ---------------------------------------------------------------------------------

    @property
    def position_m(self) -> float:
        """The estimated front end, unwrapped on a ring [m]."""
        return self.locator.position_m

    @property
    def speed_mps(self) -> float:
        """The estimated speed [m/s]."""
        return self.locator.speed_mps

    @property
    def ato_state(self) -> m.AtoState:
        return self.controller.state

    @property
    def engaged(self) -> bool:
        return self.controller.state in _ENGAGED

    def _note(self, severity: m.EventSeverity, code: str, text: str) -> None:
        self.events.append(StackEvent(severity, code, text))

    # -- journey and MA --------------------------------------------------------------------------

    def review_journey(self, profile: m.JourneyProfile) -> tuple[bool, str | None]:
        """Accept a journey profile (reviewed against the track data, then planned from here)
        or reject it with the reason."""
        if self.engaged:
            return False, "ATO engaged: disengage before changing the journey"
        review = self.track_database.review(profile)
        if not review.accepted:
            return False, review.reason
        chainage = self.track_map.normalise(self.position_m)
        try:
            plan = plan_journey(
                self.track_map,
                self.model,
                profile,
                start_chainage_m=chainage,
                energy=self.energy_plans,
            )
        except InfeasibleLegError as exc:
            self.track_database.journey = None
            return False, f"infeasible: {exc}"
        self.journey_plan, self._planned_at_m = plan, self.position_m
        self._journey_started = False
        self.driving.skipped.clear()
        return True, None

    def receive_movement_authority(self, message: m.MovementAuthorityMessage, now_s: float) -> str:
        """Hand an RBC message to ETCS; what happened, for the event log."""
        if message.authority is None:
            self.etcs.emergency_stop(now_s)
            return "revoked: emergency stop"
        change = self.etcs.receive_movement_authority(
            authority_from_extent(message.authority),
            now_s,
            track_description_m=message.authority.track_description_m,
        )
        return change.value

    def receive_speed_restriction(self, message: m.SpeedRestrictionMessage, now_s: float) -> str:
        """Put an RBC's TSR in force on the TrackMap that ETCS and the ADF share, or revoke it;
        the ADF replans the current leg. What happened, for the event log.

        Raises
        ------
        ValueError
            If it is for another line, or its range is not on this line.
        """
        track_map = self.track_map
        if message.line_id != track_map.line.id:
            raise ValueError(
                f"TSR on line {message.line_id!r}, the vehicle is on {track_map.line.id!r}"
            )
        if message.speed_mps is None:
            if not track_map.revoke_temporary_speed_restriction(message.restriction_id):
                return f"TSR {message.restriction_id} not in force: nothing to revoke"
            what = f"TSR {message.restriction_id} revoked"
        else:
            track_map.add_temporary_speed_restriction(
                TemporarySpeedRestriction(
                    id=message.restriction_id,
                    start_m=message.start_m,
                    end_m=message.end_m,
                    speed_mps=message.speed_mps,
                )
            )
            what = (
                f"TSR {message.restriction_id} {message.speed_mps / MPS_PER_KMH:.0f} km/h over "
                f"{message.start_m:.0f}..{message.end_m:.0f} m"
            )
        self.driving.speed_limits_changed(
            now_s, position_m=self.position_m, speed_mps=self.speed_mps
        )
        return what

    # -- operator requests -----------------------------------------------------------------------

    def refusal(self, body: m.CommandBody) -> str | None:
        """Why a command cannot be obeyed now, if it cannot (checked on arrival)."""
        state = self.controller.state
        if isinstance(body, m.EngageCommand):
            if self.journey_plan is None:
                return "ATO-OB not available: no journey profile accepted"
            if state is not m.AtoState.READY:
                reasons = self.controller.output.unavailable_reasons + (
                    self.controller.output.not_ready_reasons
                )
                failed = ", ".join(str(r) for r in reasons) or "conditions pending"
                return f"ATO-OB is {state.value}, not ready ({failed})"
        if isinstance(body, m.DisengageCommand) and state not in _ENGAGED:
            return "ATO-OB is not engaged"
        if isinstance(body, m.RemoteDrivingTargetCommand):
            if state in _ENGAGED:
                return "ATO engaged: disengage before remote driving"
            limit = self.track_map.speed_limit_mps(self.position_m)
            if body.target_speed_mps > limit:
                return f"target {body.target_speed_mps:.2f} m/s above line speed {limit:.2f} m/s"
        if isinstance(body, m.EmergencyBrakeCommand | m.OperatorConfirmCommand):
            if not self.vital_links:
                return "no Vital Control fitted"
            if isinstance(body, m.OperatorConfirmCommand):
                return self.vital_links[0].refusal(body.request, body.number)
        if isinstance(body, m.SkipStopCommand):
            return self._skip_refusal(body.timing_point_id)
        if isinstance(body, m.TrainHoldCommand) and self.journey_plan is None:
            return "no journey profile accepted"
        return None

    def _skip_refusal(self, timing_point_id: str) -> str | None:
        driving = self.driving
        if driving.journey is not None:
            driving.next_stop(self.position_m)  # brings the served stops up to date
            ahead = driving.journey.stops[driving.served :]
        elif self.journey_plan is not None:
            ahead = self.journey_plan.stops
        else:
            return "no journey profile accepted"
        for stop in ahead:
            if stop.timing_point_id == timing_point_id:
                if stop.end_of_journey:
                    return f"{timing_point_id} ends the journey: it cannot be skipped"
                return None
        return f"{timing_point_id} is not a stopping point ahead on the journey"

    def skip_stop(self, timing_point_id: str, now_s: float) -> None:
        """The driver's "Skip Stopping Point" (checked by :meth:`refusal`)."""
        self.driving.skip_stop(
            timing_point_id, now_s, position_m=self.position_m, speed_mps=self.speed_mps
        )

    def train_hold(self, hold: bool, now_s: float) -> None:
        """Train hold on or off (checked by :meth:`refusal`)."""
        self.driving.set_hold(hold, now_s, position_m=self.position_m, speed_mps=self.speed_mps)

    def remote(self, target_mps: float, now_s: float) -> None:
        self.remote_selected = True
        self.remote_target_mps = target_mps
        self.driving.remote(
            target_mps,
            now_s,
            speed_mps=self.speed_mps,
            gradient_permille=self.track_map.gradient_permille(self.position_m),
        )

    def engage(self, now_s: float) -> str | None:
        """The remote driver's "ATO Engage"; the refusal, if refused."""
        try:
            self.controller.engage(now_s)
        except RequestRefusedError as exc:
            return str(exc)
        self.remote_selected = False
        self._start_journey(now_s)
        return None

    def disengage(self, now_s: float) -> str | None:
        try:
            self.controller.disengage(now_s)
        except RequestRefusedError as exc:
            return str(exc)
        return None

    def _start_journey(self, now_s: float) -> None:
        if (
            self._journey_started
            or self.journey_plan is None
            or self.track_database.journey is None
        ):
            return
        if abs(self.position_m - self._planned_at_m) > REPLAN_MOVED_M:
            self.journey_plan = plan_journey(
                self.track_map,
                self.model,
                self.track_database.journey,
                start_chainage_m=self.track_map.normalise(self.position_m),
                energy=self.energy_plans,
            )
        self.driving.start_journey(self.journey_plan, now_s, position_m=self.position_m)
        self._journey_started = True

    # -- Vital Control ---------------------------------------------------------------------------

    def emergency_brake(self, now_s: float) -> float:
        """The EB's share of the full brake force on the plant now, 0 to 1 (0 without a VC)."""
        return 0.0 if self.vital is None else self.vital.emergency_brake(now_s)

    def operator_emergency_brake(self) -> str | None:
        """The operator's EB, relayed to the VC; the refusal, if refused."""
        if not self.vital_links:
            return "no Vital Control fitted"
        for link in self.vital_links:
            link.request_emergency_brake()
        return None

    def operator_confirm(self, kind: m.OperatorRequestKind, number: int) -> str | None:
        """The operator's answer to a VC request; the refusal, if refused."""
        if not self.vital_links:
            return "no Vital Control fitted"
        refusals = [link.confirm(kind, number) for link in self.vital_links]
        return refusals[0]

    def step_vital_link(self, now_s: float) -> None:
        """The ATO-OB answers the VC's requests; new operator requests and VC events are noted."""
        failed = self.controller.state is m.AtoState.FAILURE
        for link in self.vital_links:
            link.step(now_s, failed=failed)
        if self.vital is None:
            return
        for request in self.vital_links[0].take_raised():
            text = f"{request.kind.value} request {request.number}"
            if request.deadline_s is not None:
                text += f", answer by {request.deadline_s:.2f} s"
            urgent = request.deadline_s is not None
            severity = m.EventSeverity.WARNING if urgent else m.EventSeverity.INFO
            self._note(severity, f"vc.request.{request.kind.value}", text)
        vc = self.vital.boards[0].vc
        seen_b, seen_c = self._vc_events_seen
        events = sorted(
            vc.task_b.events[seen_b:] + vc.task_c.events[seen_c:], key=lambda e: e.time_s
        )
        self._vc_events_seen = (len(vc.task_b.events), len(vc.task_c.events))
        for event in events:
            serious = event.kind in _VC_ALARMS
            self._note(
                m.EventSeverity.ERROR if serious else m.EventSeverity.INFO,
                f"vc.{event.kind.value}",
                f"{event.task}: {event.detail}",
            )
        pair = self.vital.pair
        if pair is not None:
            for pair_event in pair.events[self._pair_events_seen :]:
                self._note(
                    m.EventSeverity.ERROR,
                    f"vc.pair.{pair_event.kind.value}",
                    f"replica {pair_event.replica}: {pair_event.detail}",
                )
            self._pair_events_seen = len(pair.events)

    def _follow_relay(self, now_s: float) -> None:
        """The relay's contact switches the ETCS-OB's power: isolated, or inserted and started."""
        assert self.vital is not None
        isolated = self.vital.etcs_isolated(now_s)
        if isolated and not self.etcs.isolated:
            self.etcs.isolate(now_s)
        elif not isolated and self.etcs.isolated:
            self.etcs.insert(now_s)
            self.etcs.start_of_mission(now_s)

    def vital_status(self) -> m.VitalControlStatus | None:
        """The VC's state for the status report, with the requests waiting for the operator."""
        if self.vital is None:
            return None
        out = self.vital.outputs
        return m.VitalControlStatus(
            eb_commanded=self.vital.eb_commanded,
            system_decay=out.system_decay,
            decay_reasons=tuple(reason.value for reason in out.decay_reasons),
            eb_conditions=tuple(int(condition) for condition in out.eb_conditions),
            etcs_isolated=out.etcs_isolated,
            supervision_state=out.task_b_state.value,
            brake_state=out.brake_state.value,
            etcs_state=out.etcs_state.value,
            standstill=out.standstill,
            odometry_efficient=out.odometry_efficient,
            speed_mps=None if out.speed_mps is None else max(out.speed_mps, 0.0),
            replicas=len(self.vital.boards),
            pair_tripped=self.vital.tripped,
            operator_requests=tuple(
                m.OperatorRequest(
                    kind=p.kind,
                    number=p.number,
                    raised_s=p.raised_s,
                    deadline_s=p.deadline_s,
                    confirmed=p.confirmed,
                )
                for p in self.vital_links[0].pending
            ),
        )

    # -- tasks -----------------------------------------------------------------------------------

    def step_etcs(
        self,
        now_s: float,
        wheels: Sequence[WheelReading] = (),
        balises: Sequence[BaliseDetection] = (),
    ) -> None:
        """One ETCS cycle on the axle-end sensors' readings and the balise groups the BTM read
        since the last cycle; each group read is also a fix for the sensor fusion and a
        telegram header for the VC."""
        if self.vital is not None:
            self._follow_relay(now_s)
        output = self.etcs.step_on_sensors(now_s, wheels, balises)
        for event in output.linking_events:
            what = "reaction applied" if event.applied else "reported only"
            self._note(
                m.EventSeverity.WARNING,
                f"etcs.linking.{event.fault.value}",
                f"balise group {event.balise_group_id} expected at "
                f"{event.expected_location_m:.1f} m ± {event.location_accuracy_m:.1f} m: "
                f"{event.reaction.value}, {what}",
            )
        for detection in balises:
            self.locator.fix(detection.group.position_m, detection.time_s)
        reading = self.etcs.last_balise_reading
        if reading is not self._balise_reading:
            self._balise_reading = reading
            if reading is not None and self.vital is not None:
                self.vital.balise_read(reading.header)

    def _inputs(self, now_s: float) -> AtoObInputs:
        position, speed = self.position_m, self.speed_mps
        driving = self.driving
        stopped_at = driving.stopped_at(position, speed) if self._journey_started else None
        if stopped_at is not None and stopped_at.timing_point_id != self._overrun_noted:
            overrun_m = driving.overrun_m(stopped_at, position)
            if overrun_m > 0.0:
                self._overrun_noted = stopped_at.timing_point_id
                self._note(
                    m.EventSeverity.WARNING,
                    "journey.stop_overrun",
                    f"stopped {overrun_m:.1f} m past {stopped_at.timing_point_id}'s "
                    "tolerance: the brakes gave less than asked",
                )
        next_stop = driving.next_stop(position) if self._journey_started else None
        if not self._journey_started and self.journey_plan is not None:
            next_stop = self.journey_plan.stops[0]
        output = self.etcs.output
        ahead = output.end_of_authority_distance_m if output is not None else None
        journey_s = driving.journey_time_s(now_s)
        dwell = stopped_at is None or journey_s >= driving.departure_s(stopped_at)
        return AtoObInputs(
            etcs=None if output is None else EtcsStatus.from_output(output, received_s=now_s),
            journey_profile_valid=self.journey_plan is not None,
            journey_profile_accepted=self.journey_plan is not None,
            track_data_version_matches=self.track_database.versions_match,
            localisation_valid=self.locator.localisation_valid,
            end_of_journey_reached=stopped_at is not None and stopped_at.end_of_journey,
            standstill=speed < STANDSTILL_MPS,
            at_stopping_point=stopped_at is not None,
            dwell_elapsed=dwell,
            movement_authority_allows_departure=ahead is not None and ahead > MIN_AUTHORITY_M,
            distance_to_next_stop_sufficient=next_stop is not None,
            trackside_session_alive=self.session_alive,
            remote_driving_selected=self.remote_selected,
            other_emergency_brake=self.vital is not None and self.vital.eb_commanded,
            internal_fault=self.internal_fault,
        )

    def step_control(self, now_s: float, applied_force_n: float = 0.0) -> float:
        """The ATO-OB controller and the ADF: the force demand [N] until the next step.

        ``applied_force_n`` is the drives' and brakes' feedback [N] (the ADF's bumpless
        transfer starts from it)."""
        out = self.controller.step(now_s, self._inputs(now_s))
        if out.automatic_driving_requested != self._ad_requested:
            self._ad_requested = out.automatic_driving_requested
            self.etcs.request_automatic_driving(self._ad_requested, now_s)
        driving = self.driving
        mode, traction = out.mode_request, out.traction_allowed
        if self.remote_selected and not self.engaged and out.state is not m.AtoState.FAILURE:
            mode, traction = ModeRequest.REMOTE, True
        if mode is ModeRequest.AUTONOMOUS and not driving.sc.needs_autonomous:
            self._start_journey(now_s)
            driving.engage(now_s)
        elif mode is ModeRequest.OFF and driving.state is not m.ScState.OFF:
            driving.disengage(now_s)
        elif mode is ModeRequest.REMOTE and driving.state is m.ScState.OFF:
            self.remote(self.remote_target_mps or 0.0, now_s)
        if out.stop_at_next_stopping_point and not driving.fallback_active and self.engaged:
            driving.stop_at_next_stopping_point(
                now_s, position_m=self.position_m, speed_mps=self.speed_mps
            )
            self._note(
                m.EventSeverity.WARNING,
                "ato.fallback_stop",
                "trackside lost: stopping at the next stopping point",
            )
        elif driving.fallback_active and self.engaged and not out.stop_at_next_stopping_point:
            driving.resume_journey(now_s, position_m=self.position_m, speed_mps=self.speed_mps)
            self._note(
                m.EventSeverity.INFO,
                "ato.fallback_cancelled",
                "trackside back: the journey goes on",
            )
        etcs = self.etcs.output
        ahead = [
            d
            for d in (out.end_of_authority_distance_m, out.supervised_location_distance_m)
            if d is not None
        ]
        permitted = out.permitted_speed_mps if etcs is not None else math.inf
        driving.set_etcs_limits(
            permitted, min(ahead) if ahead else None, position_m=self.position_m
        )
        etcs_brake = etcs is not None and (etcs.service_brake or etcs.emergency_brake)
        vc_braking = self.vital is not None and self.vital.eb_commanded
        if vc_braking != self._vc_braking and self.remote_selected:
            # An EB ends the remote driver's manoeuvre: he must ask for speed again, and what
            # he asks is driven from where the train stands once the EB is released.
            if vc_braking:
                self.remote_target_mps = 0.0
            driving.restart_remote(self.remote_target_mps or 0.0, now_s, speed_mps=self.speed_mps)
        self._vc_braking = vc_braking
        self.force_demand_n = driving.step(
            now_s,
            position_m=self.position_m,
            speed_mps=self.speed_mps,
            applied_force_n=applied_force_n,
            gradient_permille=self.track_map.gradient_permille(self.position_m),
            force_limits_n=self.force_limits_n(self.speed_mps),
            traction_allowed=traction and not (etcs is not None and etcs.traction_cut),
            service_brake=out.full_service_brake or etcs_brake or vc_braking,
        )
        return self.force_demand_n
