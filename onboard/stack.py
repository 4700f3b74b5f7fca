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
from dataclasses import dataclass
from typing import Protocol

from onboard.adf.function import DrivingFunction
from onboard.adf.journey import JourneyPlan, JourneyStop
from onboard.adf.supervisor import ModeRequest
from onboard.ato_ob import (
    AtoObController,
    AtoObInputs,
    AtoObOutput,
    EtcsStatus,
    RequestRefusedError,
)
from onboard.ato_ob.vital_link import VitalLink
from onboard.energy_manager import EnergyManager, EnergyManagerParameters
from onboard.etcs import URV_ODOMETER, EtcsOnboard
from onboard.events import StackEvent
from onboard.journey_keeper import JourneyKeeper
from onboard.plant.point_mass import PointMassParameters
from onboard.plant.readings import BaliseDetection, WheelReading
from onboard.rbc_messages import receive_movement_authority, receive_speed_restriction
from onboard.track_database_manager import TrackDatabaseManager
from onboard.vc.installation import VcInstallation
from onboard.vital_interface import VitalInterface
from protocol import messages as m
from trackdb import TrackMap

__all__ = [
    "ControlInputs",
    "ForceLimits",
    "Locator",
    "OnboardStack",
    "StackEvent",
    "authority_ahead_m",
]

STANDSTILL_MPS = 0.01
MIN_AUTHORITY_M = 5.0
"""An MA shorter than this ahead does not allow leaving a platform."""
DEPARTURE_PREPARATION_S = 1.5
"""The dwell counts as elapsed this long before a stop's departure [s]: ATO engages, the brake
is released and the traction built up while the reference still stands (``onboard.adf.
autonomous.STANDING_MARGIN_N``), so that the train leaves with its reference. Engaged at the
departure, the brake's release and the demand's rate bound left it 0.6–1 s behind, which the
NMPC caught up by overshooting the plan's speed and braking the excess away (docs/scenarios.md,
"The energy certificate")."""
REPLAN_MOVED_M = 1.0
"""A journey planned at acceptance is replanned at engagement if the vehicle moved more."""
_ENGAGED = (m.AtoState.ENGAGED, m.AtoState.DISENGAGING)


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


@dataclass(frozen=True)
class ControlInputs:
    """What the control step takes besides the stack's own parts."""

    applied_force_n: float = 0.0
    """The drives' and brakes' feedback [N] (the ADF's bumpless transfer starts from it)."""
    session_alive: bool = False
    """Whether a session with the trackside is established."""
    internal_fault: bool = False
    """An ATO-OB internal fault (injected by scenario runs): the controller goes to FA."""


class OnboardStack:
    """ETCS + ATO-OB controller + ADF for one vehicle.

    Parameters
    ----------
    track_map : TrackMap
        The onboard's track data (ETCS and the ADF share its TSRs).
    locator : Locator
        The sensor-fusion localisation the ATO-OB and the ADF use.
    model : PointMassParameters
        The vehicle's data the ADF plans with.
    force_limits_n : ForceLimits
        The vehicle's (min, max) force [N] at a speed.
    start_position_m : float
        Where the vehicle was powered up [m] (its stored position): ETCS's odometry starts
        there, with the national location accuracy until the first balise group.
    start_s : float
        The power-up instant [s].
    energy_plans : bool
        Plan journeys energy-minimised (else the plain LSPB).
    vital : VcInstallation, optional
        The Vital Control fitted to the vehicle, if any (its tasks run on the node).
    energy : EnergyManagerParameters, optional
        The vehicle's energy data for the Energy Manager (default: the URV's).
    """

    def __init__(
        self,
        track_map: TrackMap,
        locator: Locator,
        model: PointMassParameters,
        force_limits_n: ForceLimits,
        *,
        start_position_m: float = 0.0,
        start_s: float = 0.0,
        energy_plans: bool = True,
        vital: VcInstallation | None = None,
        energy: EnergyManagerParameters | None = None,
    ) -> None:
        self.track_map = track_map
        self.locator = locator
        self.model = model
        self.force_limits_n = force_limits_n
        self.energy_plans = energy_plans
        self.vital = vital
        self.vital_interface = VitalInterface(vital)
        self.track_database = TrackDatabaseManager(track_map)
        self.etcs = EtcsOnboard(
            track_map, position_m=start_position_m, start_s=start_s, odometer=URV_ODOMETER
        )
        self.etcs.start_of_mission(start_s)
        self.controller = AtoObController(start_s=start_s)
        self.driving = DrivingFunction(track_map, model)
        self.energy = EnergyManager(energy or EnergyManagerParameters.for_urv(), model)
        self.journey = JourneyKeeper(
            track_map, model, self.track_database, self.driving, energy_plans=energy_plans
        )
        self.journey.energy = self.energy
        self.remote_selected = False
        self.remote_target_mps: float | None = None
        self.force_demand_n = 0.0
        self._ad_requested = False
        self._overrun_noted: str | None = None
        self._events: list[StackEvent] = []
        self._balise_reading = self.etcs.last_balise_reading
        self._vc_braking = self.vital_interface.eb_commanded

    @property
    def vital_links(self) -> list[VitalLink]:
        """The ATO-OB's request/response links, one per VC board (none without a VC)."""
        return self.vital_interface.links

    @property
    def journey_plan(self) -> JourneyPlan | None:
        """The accepted journey's plan (None: no journey profile accepted)."""
        return self.journey.plan

    def take_events(self) -> list[StackEvent]:
        """What the stack noted for the event log since the last call, oldest first."""
        events, self._events = [*self._events, *self.journey.take_events()], []
        return events

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
        self._events.append(StackEvent(severity, code, text))

    # -- journey and MA --------------------------------------------------------------------------

    def review_journey(self, profile: m.JourneyProfile) -> tuple[bool, str | None]:
        """Accept a journey profile (reviewed against the track data, then planned from here)
        or reject it with the reason."""
        if self.engaged:
            return False, "ATO engaged: disengage before changing the journey"
        return self.journey.review(profile, self.position_m)

    def receive_movement_authority(self, message: m.MovementAuthorityMessage, now_s: float) -> str:
        """Hand an RBC message to ETCS; what happened, for the event log."""
        return receive_movement_authority(self.etcs, message, now_s)

    def receive_speed_restriction(self, message: m.SpeedRestrictionMessage, now_s: float) -> str:
        """Put an RBC's TSR in force, or revoke it (:func:`~onboard.rbc_messages.
        receive_speed_restriction`); what happened, for the event log."""
        what, changed = receive_speed_restriction(self.track_map, message)
        if changed:
            self.driving.speed_limits_changed(
                now_s, position_m=self.position_m, speed_mps=self.speed_mps
            )
        return what

    # -- operator requests -----------------------------------------------------------------------

    def skip_stop(self, timing_point_id: str, now_s: float) -> None:
        """The driver's "Skip Stopping Point" (checked by :mod:`onboard.commands`)."""
        self.driving.skip_stop(
            timing_point_id, now_s, position_m=self.position_m, speed_mps=self.speed_mps
        )

    def train_hold(self, hold: bool, now_s: float) -> None:
        """Train hold on or off (checked by :mod:`onboard.commands`)."""
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
        self.journey.start(now_s, self.position_m)

    # -- Vital Control ---------------------------------------------------------------------------

    def emergency_brake(self, now_s: float) -> float:
        """The EB's share of the full brake force on the plant now, 0 to 1 (0 without a VC)."""
        return self.vital_interface.emergency_brake(now_s)

    def step_vital_link(self, now_s: float) -> None:
        """The ATO-OB answers the VC's requests; new operator requests and VC events are noted."""
        failed = self.controller.state is m.AtoState.FAILURE
        self._events.extend(self.vital_interface.step(now_s, ato_failed=failed))

    def vital_status(self) -> m.VitalControlStatus | None:
        """The VC's state for the status report, with the requests waiting for the operator."""
        return self.vital_interface.status()

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
        self.vital_interface.follow_relay(self.etcs, now_s)
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

    def _inputs(self, now_s: float, given: ControlInputs) -> AtoObInputs:
        position, speed = self.position_m, self.speed_mps
        stopped_at = self.driving.stopped_at(position, speed) if self.journey.started else None
        if stopped_at is not None and stopped_at.timing_point_id != self._overrun_noted:
            overrun_m = self.driving.overrun_m(stopped_at, position)
            if overrun_m > 0.0:
                self._overrun_noted = stopped_at.timing_point_id
                self._note(
                    m.EventSeverity.WARNING,
                    "journey.stop_overrun",
                    f"stopped {overrun_m:.1f} m past {stopped_at.timing_point_id}'s "
                    "tolerance: the brakes gave less than asked",
                )
        return _ato_ob_inputs(self, now_s, given, stopped_at)

    def step_control(self, now_s: float, given: ControlInputs = ControlInputs()) -> float:
        """The ATO-OB controller and the ADF: the force demand [N] until the next step."""
        out = self.controller.step(now_s, self._inputs(now_s, given))
        if out.automatic_driving_requested != self._ad_requested:
            self._ad_requested = out.automatic_driving_requested
            self.etcs.request_automatic_driving(self._ad_requested, now_s)
        traction = self._follow_mode_request(now_s, out)
        self._follow_fallback(now_s, out)
        driving, etcs = self.driving, self.etcs.output
        permitted = out.permitted_speed_mps if etcs is not None else math.inf
        driving.set_etcs_limits(permitted, authority_ahead_m(self, out), position_m=self.position_m)
        etcs_brake = etcs is not None and (etcs.service_brake or etcs.emergency_brake)
        vc_braking = self.vital_interface.eb_commanded
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
            applied_force_n=given.applied_force_n,
            gradient_permille=self.track_map.gradient_permille(self.position_m),
            force_limits_n=self.force_limits_n(self.speed_mps),
            traction_allowed=traction and not (etcs is not None and etcs.traction_cut),
            service_brake=out.full_service_brake or etcs_brake or vc_braking,
        )
        self.journey.watch_energy(now_s)
        return self.force_demand_n

    def _follow_mode_request(self, now_s: float, out: AtoObOutput) -> bool:
        """The supervisory controller follows the ATO-OB's mode request (the remote driver's
        selection prevails while ATO is not engaged); whether traction is allowed."""
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
        return traction

    def _follow_fallback(self, now_s: float, out: AtoObOutput) -> None:
        """The unattended fallback: stop at the next stopping point while the trackside is
        lost, go on with the journey once it is back."""
        driving = self.driving
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


def authority_ahead_m(stack: OnboardStack, out: AtoObOutput) -> float | None:
    """How far ahead of the fused position [m] the ADF must stop for its authority: the nearer
    of the EoA and ETCS's distance from the max-safe front end to the SvL; None without an MA.

    The EoA is a place on the track (a signal, a marker board): ETCS's location of it, measured
    from the fused position while the localisation is valid. ETCS's own distance, from its
    estimated front end, carries the drift of its odometry since the last balise group (up to
    the wheel's calibration error, 0.6 %, over the 1.7 km between the ring's groups: 10 m;
    5.4 m in a generated run), which put a train stopping 5 m short of the EoA by it 13.75 m
    short on the truth. At the EoA ETCS supervises the release speed and trips only when its
    min-safe front end (behind the truth) passes it. The SvL, which ETCS guards with its
    emergency brake, stays ETCS's measure (docs/decisions.md, "The EoA is located from the
    fused position").
    """
    etcs, eoa = stack.etcs.output, out.end_of_authority_distance_m
    from_front = None if etcs is None else etcs.end_of_authority_distance_m
    if etcs is not None and from_front is not None and stack.locator.localisation_valid:
        eoa = etcs.odometry.estimated_front_m + from_front - stack.position_m
    ahead = [d for d in (eoa, out.supervised_location_distance_m) if d is not None]
    return min(ahead) if ahead else None


def _ato_ob_inputs(
    stack: OnboardStack, now_s: float, given: ControlInputs, stopped_at: JourneyStop | None
) -> AtoObInputs:
    """The ATO-OB controller's inputs at ``now_s`` [s], the train standing at ``stopped_at``."""
    driving, plan = stack.driving, stack.journey_plan
    next_stop = driving.next_stop(stack.position_m) if stack.journey.started else None
    if not stack.journey.started and plan is not None:
        next_stop = plan.stops[0]
    output = stack.etcs.output
    ahead = output.end_of_authority_distance_m if output is not None else None
    journey_s = driving.journey_time_s(now_s)
    dwell = stopped_at is None or journey_s + DEPARTURE_PREPARATION_S >= driving.departure_s(
        stopped_at
    )
    return AtoObInputs(
        etcs=None if output is None else EtcsStatus.from_output(output, received_s=now_s),
        journey_profile_valid=plan is not None,
        journey_profile_accepted=plan is not None,
        track_data_version_matches=stack.track_database.versions_match,
        localisation_valid=stack.locator.localisation_valid,
        end_of_journey_reached=stopped_at is not None and stopped_at.end_of_journey,
        standstill=stack.speed_mps < STANDSTILL_MPS,
        at_stopping_point=stopped_at is not None,
        dwell_elapsed=dwell,
        movement_authority_allows_departure=ahead is not None and ahead > MIN_AUTHORITY_M,
        distance_to_next_stop_sufficient=next_stop is not None,
        trackside_session_alive=given.session_alive,
        remote_driving_selected=stack.remote_selected,
        other_emergency_brake=stack.vital_interface.eb_commanded,
        internal_fault=given.internal_fault,
    )
