"""EtcsOnboard: the emulated ETCS onboard, a deterministic library object called with the time.

A cycle comes one of two ways:

- :meth:`EtcsOnboard.step_on_sensors` (the train's own sensors, the onboard built with an
  ``odometer``): the wheel readings and balise detections since the last cycle. The odometer
  (:mod:`onboard.etcs.odometer`) counts the pulses into distance, speed, A_est and slip/slide;
  each detected group is read at the odometer's position interpolated to its detection time.
  Nothing is read from the TrackMap at the odometer's position.
- :meth:`EtcsOnboard.step` (given motion): the odometer's position (a chainage), the speed and
  A_est; the balise groups passed are read from the TrackMap (unless the caller passes them
  with :meth:`EtcsOnboard.pass_balise_group`).

Then it

1. relocates the odometry at each group read and checks the linked groups' expectation
   windows (:mod:`onboard.etcs.linking`), taking the linking reaction of a group missed;
2. updates the odometry's confidence interval (:mod:`onboard.etcs.odometry`);
3. applies level transitions due and runs the MA's timers;
4. takes the mode transitions whose conditions hold (:mod:`onboard.etcs.modes`);
5. supervises speed and distance for the mode and latches the commands
   (:mod:`onboard.etcs.supervision`), and returns an :class:`EtcsOutput`.

Supervision by mode:

- SB, PT: standstill supervision; moving more than D_NVROLL commands the EB (roll-away
  protection), revoked at standstill.
- SR: CSM and the MRSP's decreases under min(MRSP, V_NVSTFF); trip past D_NVSTFF.
- FS, AD: CSM, TSM of the MRSP's decreases, of the EoA and of the SvL, RSM.
- OS: as FS, with the on-sight area's speed (V_NVONSIGHT by default) as a ceiling.
- TR: EB until the trip is acknowledged at standstill; IS: nothing (the VC supervises).

Track data. The speed and gradient values come from the TrackMap, the onboard's track database.
The SSP and gradient packets (packets 27 and 21 from balise groups; with the MA from the RBC) say
how far they may be used: the EoA and SvL are held at the end of that track description. The
MRSP is min(TrackMap's MRSP with its TSRs, the train's maximum speed, the mode's limit); the CSM's
ceiling is its lowest value under the train, from the min-safe rear end to the max-safe front end.

Coordinates. On a ring the chainage wraps; inside, locations are unwrapped (they run on, lap
after lap). :class:`EtcsOutput` gives chainages for the front end and the EoA, and distances.

For the ADF: never exceed ``permitted_speed_mps``; stop within ``end_of_authority_distance_m``
(from the estimated front end) and ``supervised_location_distance_m`` (from the max-safe front
end), both of which the curves supervise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from onboard.etcs._exceptions import EtcsInputError, TransitionRefusedError
from onboard.etcs._motion import MotionSupervisor
from onboard.etcs.balises import (
    BaliseGroupReading,
    LevelTransition,
    LinkedGroup,
    balise_groups_passed,
    read_balise_group,
)
from onboard.etcs.braking import BrakingModel
from onboard.etcs.linking import LinkingEvent, LinkingFault
from onboard.etcs.localisation import Localisation, OdometerPoint
from onboard.etcs.modes import ModeChange, ModeCondition, ModeTransition, select_transition
from onboard.etcs.movement_authority import (
    AuthorityInForce,
    EtcsLevel,
    MaChange,
    MovementAuthority,
    TrackDescription,
)
from onboard.etcs.odometer import Odometer, OdometerParameters
from onboard.etcs.odometry import ConfidenceInterval, OdometryAccuracy
from onboard.etcs.output import EtcsOutput
from onboard.etcs.supervision import Demand, InterventionLatch, Monitoring, SupervisionResult
from onboard.etcs.values import (
    FIXED_VALUES,
    NATIONAL_DEFAULTS,
    URV_TRAIN_DATA,
    FixedValues,
    NationalValues,
    TrainData,
)
from onboard.plant.readings import BaliseDetection, WheelReading
from protocol.messages import EtcsMode, SupervisionStatus
from trackdb import BaliseGroup, TrackMap
from trackdb.schema import LinkReaction

__all__ = ["STANDSTILL_SPEED_MPS", "EtcsOnboard", "EtcsOutput"]

STANDSTILL_SPEED_MPS = 0.05
"""At or below this speed [m/s] the train is at standstill."""
_SUPERVISED_MODES = frozenset({EtcsMode.FS, EtcsMode.OS, EtcsMode.AD})
_STANDSTILL_MODES = frozenset({EtcsMode.SB, EtcsMode.PT})


class EtcsOnboard:
    """The ETCS onboard of one vehicle on one line.

    Parameters
    ----------
    track_map : TrackMap
        The line: MRSP, gradients, balise groups.
    train, national, fixed : TrainData, NationalValues, FixedValues
        The URV and the A.3 defaults by default.
    odometry : OdometryAccuracy, optional
        The odometer's error law: the ``odometer``'s own law when one is given
        (:meth:`OdometerParameters.accuracy`), SUBSET-041's ±(5 m + 5 %) otherwise.
    level : EtcsLevel, optional
        The starting level; the line's by default.
    position_m : float
        The front end's chainage [m] at start: the odometer's zero (on the sensor path, where
        the first wheel reading finds the train); its accuracy is Q_NVLOCACC until a balise
        group.
    start_s : float
        The time [s] at start; every call's ``now_s`` must not go back from the last.
    read_balise_groups : bool, optional
        Read the groups passed from the TrackMap in :meth:`step` (the default without an
        odometer); False when the caller passes them (as the VC forwards BTM telegrams). On
        the sensor path groups come from balise detections only.
    odometer : OdometerParameters, optional
        The wheel-sensor odometer: given, the onboard runs on the train's sensors
        (:meth:`step_on_sensors`), and :meth:`step` and :meth:`pass_balise_group` are refused.
    """

    def __init__(
        self,
        track_map: TrackMap,
        *,
        train: TrainData = URV_TRAIN_DATA,
        national: NationalValues = NATIONAL_DEFAULTS,
        fixed: FixedValues = FIXED_VALUES,
        odometry: OdometryAccuracy | None = None,
        level: EtcsLevel | None = None,
        position_m: float = 0.0,
        start_s: float = 0.0,
        read_balise_groups: bool | None = None,
        odometer: OdometerParameters | None = None,
    ) -> None:
        if not (math.isfinite(position_m) and math.isfinite(start_s)):
            raise EtcsInputError("start position and time must be finite")
        if odometer is not None and read_balise_groups:
            raise EtcsInputError("on the sensor path balise groups come from detections only")
        self.track_map = track_map
        self.braking = BrakingModel(train, national=national, fixed=fixed)
        self.train, self.national, self.fixed = train, national, fixed
        self.level = EtcsLevel(track_map.line.etcs_level) if level is None else level
        self.read_balise_groups = odometer is None and read_balise_groups is not False
        self.odometer = None if odometer is None else Odometer(odometer, start_s=start_s)
        self.mode_changes: list[ModeChange] = []
        self.linking_events: list[LinkingEvent] = []
        self.last_balise_reading: BaliseGroupReading | None = None
        self.service_brake_interventions = 0
        self.emergency_brake_interventions = 0
        self._mode = EtcsMode.SB
        self._time_s = start_s
        if odometry is None:
            odometry = OdometryAccuracy() if odometer is None else odometer.accuracy()
        self._where = Localisation(
            track_map,
            odometry,
            position_m=position_m,
            location_accuracy_m=national.q_nvlocacc_m,
            odometer=self.odometer,
        )
        self._linking_brake = False
        self._unreported: list[LinkingEvent] = []
        self._readings = 0
        self._authority: AuthorityInForce | None = None
        self._track_description = TrackDescription()
        self._level_transitions: list[LevelTransition] = []
        self._latch = InterventionLatch(
            release_at_standstill=national.emergency_brake_release_at_standstill
        )
        self._events: set[ModeCondition] = set()
        self._isolated = False
        self._automatic_driving_requested = False
        self._roll_reference_m = position_m
        self._staff_responsible_start_m = position_m
        self._motion = MotionSupervisor(track_map, self.braking)
        self._result: SupervisionResult = self._idle_result(0.0)
        self.output = self._output(self._result)

    # -- state ----------------------------------------------------------------------------------

    @property
    def mode(self) -> EtcsMode:
        """The current mode."""
        return self._mode

    @property
    def movement_authority(self) -> AuthorityInForce | None:
        """The MA in force, in track locations [m]."""
        return self._authority

    @property
    def odometry(self) -> ConfidenceInterval:
        """The confidence interval after the last cycle or balise group."""
        return self._where.interval

    @property
    def _interval(self) -> ConfidenceInterval:
        return self._where.interval

    def intervention_speed_mps(self) -> float:
        """The speed at which the last cycle's supervision would intervene [m/s]; inf when
        nothing is supervised (IS). Computed on demand: a status value."""
        return self._result.intervention_speed_mps()

    @property
    def standstill(self) -> bool:
        """Whether the last speed given was a standstill."""
        return self._where.speed_mps <= STANDSTILL_SPEED_MPS

    # -- the cycle ------------------------------------------------------------------------------

    def step(
        self, now_s: float, position_m: float, speed_mps: float, *, acceleration_mps2: float = 0.0
    ) -> EtcsOutput:
        """One supervision cycle at ``now_s`` [s].

        Parameters
        ----------
        now_s : float
            The time [s]; not before the last call's.
        position_m : float
            The odometer's front-end chainage [m] (on a ring, wrapped or not).
        speed_mps : float
            The estimated speed [m/s], ≥ 0 (the train runs forwards).
        acceleration_mps2 : float
            The estimated acceleration [m/s²], A_est of the EBI.
        """
        self._refuse_on_sensors("step")
        self._check_time(now_s)
        if not (math.isfinite(position_m) and math.isfinite(acceleration_mps2)):
            raise EtcsInputError("position and acceleration must be finite")
        if not (math.isfinite(speed_mps) and speed_mps >= 0.0):
            raise EtcsInputError(f"speed {speed_mps} m/s must be finite and ≥ 0")
        previous_m = self._where.odometer_m
        self._where.move(position_m, speed_mps, acceleration_mps2)
        if self.read_balise_groups:
            for group, odometer_m in balise_groups_passed(
                self.track_map, previous_m, self._where.odometer_m
            ):
                self._read(group, now_s, time_s=now_s, at=OdometerPoint(odometer_m=odometer_m))
        return self._cycle(now_s)

    def step_on_sensors(
        self,
        now_s: float,
        wheels: Sequence[WheelReading],
        balises: Sequence[BaliseDetection] = (),
    ) -> EtcsOutput:
        """One supervision cycle at ``now_s`` [s] on the train's own sensors.

        Parameters
        ----------
        now_s : float
            The time [s]; not before the last call's.
        wheels : sequence of WheelReading
            The axle-end readings since the last cycle, in time order (every 10 ms). The first
            one the onboard ever gets fixes the odometer's zero at the start ``position_m``.
        balises : sequence of BaliseDetection
            The balise groups the reader located since the last cycle. Each is read at the
            odometer's position interpolated to its ``time_s`` and relocates the odometry
            there, with its Q_LOCACC (or Q_NVLOCACC) and the reader's location error.
        """
        odometer = self.odometer
        if odometer is None:
            raise EtcsInputError("step_on_sensors needs an onboard built with an odometer")
        self._check_time(now_s)
        detections = sorted(balises, key=lambda detection: detection.time_s)
        if not all(math.isfinite(detection.time_s) for detection in detections):
            raise EtcsInputError("balise detection times must be finite")
        self._where.sense(odometer, wheels)
        for detection in detections:
            self._read(
                detection.group,
                now_s,
                time_s=detection.time_s,
                at=self._where.detection_position(odometer, detection.time_s),
                reader_error_m=odometer.parameters.balise_location_error_m,
            )
        return self._cycle(now_s)

    def _cycle(self, now_s: float) -> EtcsOutput:
        """The cycle once the odometer has moved and the groups are read."""
        self._where.update()
        if self._mode is not EtcsMode.IS:
            for group, fault in self._where.missed_groups():
                self._linking_fault(group, fault, now_s)
        self._apply_level_transitions()
        if self._authority is not None:
            self._authority.update(
                now_s,
                min_safe_front_m=self._interval.min_safe_front_m,
                max_safe_front_m=self._interval.max_safe_front_m,
            )
        self._evaluate_modes(now_s)
        self._events.clear()
        result = self._supervise()
        self._evaluate_modes(now_s)
        self.output = self._output(result)
        return self.output

    # -- requests -------------------------------------------------------------------------------

    def start_of_mission(self, now_s: float) -> None:
        """Start of mission in SB or PT: FS or OS with an MA on board, SR otherwise."""
        self._check_time(now_s)
        if self._mode not in _STANDSTILL_MODES:
            raise TransitionRefusedError(f"start of mission is for SB and PT, not {self._mode}")
        self._event(ModeCondition.START_IN_STAFF_RESPONSIBLE, now_s)

    def receive_movement_authority(
        self,
        authority: MovementAuthority,
        now_s: float,
        *,
        track_description_m: float | None = None,
    ) -> MaChange:
        """An MA by radio (Level 2; infill in Level 1), with the SSP and gradient it comes with.

        ``track_description_m`` [m] from the reference is how far they reach; by default up
        to the SvL. Rejected in TR and IS.
        """
        self._check_time(now_s)
        if track_description_m is not None and not (
            math.isfinite(track_description_m) and track_description_m > 0.0
        ):
            raise EtcsInputError("a track description needs a positive finite length")
        if self._mode in (EtcsMode.TR, EtcsMode.IS):
            return MaChange.REJECTED
        reference_m = self._where.locate(authority.reference_m)
        change = self._accept(authority, now_s, reference_location_m=reference_m)
        if track_description_m is None:
            track_description_m = authority.end_of_authority_m + max(
                authority.danger_point_m, authority.overlap_m
            )
        end_m = reference_m + track_description_m
        self._track_description.receive_static_speed_profile(reference_m, end_m)
        self._track_description.receive_gradient(reference_m, end_m)
        self._evaluate_modes(now_s)
        return change

    def pass_balise_group(
        self, group: BaliseGroup, now_s: float, *, position_m: float | None = None
    ) -> BaliseGroupReading:
        """The front end passed ``group`` when the odometer read ``position_m`` (chainage)."""
        self._refuse_on_sensors("pass_balise_group")
        self._check_time(now_s)
        odometer_m = (
            self._where.odometer_m if position_m is None else self._where.unwrap(position_m)
        )
        reading = self._read(group, now_s, time_s=now_s, at=OdometerPoint(odometer_m=odometer_m))
        self._where.update()
        self._evaluate_modes(now_s)
        self._events.clear()
        return reading

    def acknowledge_trip(self, now_s: float) -> None:
        """The trip acknowledged: TR → PT, at standstill only."""
        self._check_time(now_s)
        if self._mode is not EtcsMode.TR:
            raise TransitionRefusedError(f"no trip to acknowledge in {self._mode}")
        if not self.standstill:
            raise TransitionRefusedError("a trip is acknowledged at standstill only")
        self._event(ModeCondition.TRIP_ACKNOWLEDGED, now_s)

    @property
    def isolated(self) -> bool:
        """The ETCS-OB's power is cut (by the VC's relay): mode IS."""
        return self._isolated

    def isolate(self, now_s: float) -> None:
        """ETCS isolated (the VC's relay): IS from any mode, commands dropped."""
        self._check_time(now_s)
        self._isolated = True
        self._evaluate_modes(now_s)

    def insert(self, now_s: float) -> None:
        """ETCS inserted again: IS → SB."""
        self._check_time(now_s)
        if not self._isolated:
            raise TransitionRefusedError("ETCS is not isolated")
        self._isolated = False
        self._evaluate_modes(now_s)

    def request_automatic_driving(self, engaged: bool, now_s: float) -> None:
        """ATO engaged (FS → AD when the conditions hold) or disengaged (AD → FS)."""
        self._check_time(now_s)
        self._automatic_driving_requested = engaged
        self._evaluate_modes(now_s)

    def emergency_stop(self, now_s: float) -> None:
        """An unconditional emergency stop from the RBC: trip in SR, FS, OS and AD."""
        self._check_time(now_s)
        self._event(ModeCondition.EMERGENCY_STOP, now_s)

    # -- internals: time, coordinates, events --------------------------------------------------

    def _refuse_on_sensors(self, call: str) -> None:
        if self.odometer is not None:
            raise EtcsInputError(f"{call} gives motion; this onboard runs on its sensors")

    def _check_time(self, now_s: float) -> None:
        if not math.isfinite(now_s) or now_s < self._time_s:
            raise EtcsInputError(f"time {now_s} s is not finite or before {self._time_s} s")
        self._time_s = now_s

    def _event(self, condition: ModeCondition, now_s: float) -> None:
        self._events.add(condition)
        self._evaluate_modes(now_s)
        self._events.discard(condition)

    # -- internals: balise groups, MA, track description ---------------------------------------

    def _read(
        self,
        group: BaliseGroup,
        now_s: float,
        *,
        time_s: float,
        at: OdometerPoint,
        reader_error_m: float = 0.0,
    ) -> BaliseGroupReading:
        """Read ``group`` found at ``time_s`` [s], when the odometer was ``at``; the reader's
        location error [m] adds to the group's accuracy."""
        location_m = self._where.locate(group.position_m)
        link = self._where.linking.announcement(group.id)
        reading = read_balise_group(
            group,
            location_m=location_m,
            time_s=time_s,
            linked=link is not None,
            message_counter=self._readings,
        )
        self._readings += 1
        self.last_balise_reading = reading
        if self._mode is EtcsMode.IS:
            return reading
        accuracy_m = self.national.q_nvlocacc_m if link is None else link.location_accuracy_m
        faults = self._where.relocate(
            group.id,
            location_m,
            at=at,
            location_accuracy_m=accuracy_m + reader_error_m,
            linked_groups=reading.linked_groups,
        )
        for linked, fault in faults:
            self._linking_fault(linked, fault, now_s)
        if self._mode is EtcsMode.TR:
            return reading
        if reading.static_speed_profile_end_m is not None:
            end_m = reading.static_speed_profile_end_m
            self._track_description.receive_static_speed_profile(location_m, end_m)
        if reading.gradient_end_m is not None:
            self._track_description.receive_gradient(location_m, reading.gradient_end_m)
        if reading.level_transition is not None:
            self._level_transitions.append(reading.level_transition)
        if reading.movement_authority is not None and self.level is EtcsLevel.LEVEL_1:
            self._accept(reading.movement_authority, now_s, reference_location_m=location_m)
        result = self._result
        if (
            self._mode in _SUPERVISED_MODES
            and self._authority is not None
            and result.monitoring is Monitoring.RELEASE_SPEED
            and location_m >= self._authority_locations()[0]
        ):
            self._events.add(ModeCondition.BALISE_GROUP_AT_END_OF_AUTHORITY)
        return reading

    def _linking_fault(self, group: LinkedGroup, fault: LinkingFault, now_s: float) -> None:
        """A linked group not read where expected: its reaction in FS, OS and AD."""
        applied = self._mode in _SUPERVISED_MODES
        event = LinkingEvent(
            time_s=now_s,
            balise_group_id=group.balise_group_id,
            expected_location_m=group.location_m,
            location_accuracy_m=group.location_accuracy_m,
            fault=fault,
            reaction=group.reaction,
            applied=applied,
        )
        self.linking_events.append(event)
        self._unreported.append(event)
        if not applied:
            return
        if group.reaction is LinkReaction.TRAIN_TRIP:
            self._events.add(ModeCondition.LINKING_REACTION)
        elif group.reaction is LinkReaction.SERVICE_BRAKE:
            self._linking_brake = True

    def _accept(
        self, authority: MovementAuthority, now_s: float, *, reference_location_m: float
    ) -> MaChange:
        new = AuthorityInForce.resolve(
            authority, reference_location_m=reference_location_m, now_s=now_s
        )
        old = self._authority
        self._authority = new
        if old is None:
            return MaChange.NEW
        if new.end_of_authority_m > old.end_of_authority_m:
            return MaChange.EXTENDED
        if new.end_of_authority_m < old.end_of_authority_m:
            return MaChange.SHORTENED
        return MaChange.UNCHANGED

    def _authority_locations(self) -> tuple[float, float]:
        """(EoA, SvL) [m], held at the end of the track description (§3.7)."""
        if self._authority is None:  # pragma: no cover - callers check
            raise EtcsInputError("no movement authority")
        return self._track_description.held_authority_m(self._authority)

    def _apply_level_transitions(self) -> None:
        front_m = self._interval.estimated_front_m
        due = [t for t in self._level_transitions if front_m >= t.location_m]
        for transition in due:
            self.level = transition.level
            self._level_transitions.remove(transition)

    # -- internals: modes -----------------------------------------------------------------------

    def _conditions(self) -> set[ModeCondition]:
        conditions = set(self._events)
        conditions.add(ModeCondition.ISOLATED if self._isolated else ModeCondition.INSERTED)
        front = self._interval
        if self._authority is not None:
            eoa_m, _ = self._authority_locations()
            if front.min_safe_front_m > eoa_m:
                conditions.add(ModeCondition.END_OF_AUTHORITY_PASSED)
            span = self._track_description.span_m
            if span is not None and span[0] <= front.estimated_front_m:
                if self._in_on_sight_area():
                    conditions.add(ModeCondition.ON_SIGHT_AUTHORITY)
                else:
                    conditions.add(ModeCondition.AUTHORITY_AND_TRACK_DESCRIPTION)
        sr_limit_m = self._staff_responsible_start_m + self.national.d_nvstff_m
        if self._mode is EtcsMode.SR and front.min_safe_front_m > sr_limit_m:
            conditions.add(ModeCondition.STAFF_RESPONSIBLE_DISTANCE_PASSED)
        commands = self._latch.commands
        braking = commands.service_brake or commands.emergency_brake
        if braking:
            conditions.add(ModeCondition.BRAKE_COMMANDED)
        if not self._automatic_driving_requested:
            conditions.add(ModeCondition.AUTOMATIC_DRIVING_DISENGAGED)
        elif not braking and self._track_description_under_train():
            conditions.add(ModeCondition.AUTOMATIC_DRIVING_ENGAGED)
        return conditions

    def _in_on_sight_area(self) -> bool:
        authority = self._authority
        if authority is None or authority.authority.on_sight is None:
            return False
        area = authority.authority.on_sight
        start_m = authority.reference_location_m + area.start_m
        end_m = authority.reference_location_m + area.end_m
        # The area holds from the front end's entry until the rear end has left it.
        return start_m <= self._interval.estimated_front_m < end_m + self.train.length_m

    def _track_description_under_train(self) -> bool:
        span = self._track_description.span_m
        rear_m = self._interval.min_safe_front_m - self.train.length_m
        return span is not None and span[0] <= rear_m

    def _evaluate_modes(self, now_s: float) -> None:
        for _ in range(4):
            transition = select_transition(self._mode, self._conditions(), self.level)
            if transition is None:
                return
            self._enter(transition, now_s)

    def _enter(self, transition: ModeTransition, now_s: float) -> None:
        target = transition.target
        self.mode_changes.append(
            ModeChange(time_s=now_s, source=self._mode, target=target, transition=transition)
        )
        self._mode = target
        self._events.discard(transition.condition)
        front_m = self._interval.estimated_front_m
        if target in (EtcsMode.TR, EtcsMode.IS):
            self._authority = None
            self._track_description.clear()
            self._automatic_driving_requested = False
            self._linking_brake = False
            self._events.clear()
        if target is EtcsMode.IS:
            self._latch.reset()
        if target in _STANDSTILL_MODES:
            self._roll_reference_m = front_m
        if target is EtcsMode.SR:
            self._staff_responsible_start_m = front_m
        if transition.condition is ModeCondition.BRAKE_COMMANDED:
            self._automatic_driving_requested = False

    # -- internals: supervision -----------------------------------------------------------------

    def _idle_result(self, permitted_mps: float) -> SupervisionResult:
        return SupervisionResult(
            demand=Demand(),
            monitoring=Monitoring.CEILING_SPEED,
            permitted_speed_mps=permitted_mps,
            ceiling_speed_mps=permitted_mps,
            target=None,
            target_distance_m=None,
            release_speed_mps=None,
            ceiling_intervention_mps=math.inf if self._mode is EtcsMode.IS else permitted_mps,
        )

    def _supervise(self) -> SupervisionResult:
        mode = self._mode
        if mode is EtcsMode.IS:
            self._latch.reset()
            result = self._idle_result(self._motion.ceiling_mps(self._interval, math.inf))
        elif mode in _SUPERVISED_MODES or mode is EtcsMode.SR:
            result = self._supervise_motion(mode)
            self._latch_commands(self._with_linking_brake(result.demand), forced=False)
        else:
            forced = mode is EtcsMode.TR
            if mode in _STANDSTILL_MODES:
                if self.standstill:
                    self._roll_reference_m = self._interval.estimated_front_m
                moved_m = abs(self._interval.estimated_front_m - self._roll_reference_m)
                forced = moved_m > self.national.d_nvroll_m
            result = self._idle_result(0.0)
            self._latch_commands(result.demand, forced=forced)
        self._result = result
        return result

    def _with_linking_brake(self, demand: Demand) -> Demand:
        """The linking reaction's service brake (the EB without one), held to standstill."""
        if self._linking_brake and self.standstill:
            self._linking_brake = False
        if not self._linking_brake:
            return demand
        service = self.train.service_brake_available
        return demand.combined(
            Demand(
                status=SupervisionStatus.INTERVENTION,
                service_brake=service,
                emergency_brake=not service,
            )
        )

    def _latch_commands(self, demand: Demand, *, forced: bool) -> None:
        before = self._latch.commands
        after = self._latch.update(
            demand, standstill=self.standstill, forced_emergency_brake=forced
        )
        self.service_brake_interventions += after.service_brake and not before.service_brake
        self.emergency_brake_interventions += after.emergency_brake and not before.emergency_brake

    def _mode_limit_mps(self, mode: EtcsMode) -> float:
        limit_mps = self.train.max_speed_mps
        if mode is EtcsMode.SR:
            limit_mps = min(limit_mps, self.national.v_nvstff_mps)
        if mode is EtcsMode.OS and self._authority is not None:
            area = self._authority.authority.on_sight
            speed_mps = None if area is None else area.speed_mps
            limit_mps = min(limit_mps, speed_mps or self.national.v_nvonsight_mps)
        return limit_mps

    def _supervise_motion(self, mode: EtcsMode) -> SupervisionResult:
        authority_m = release_mps = None
        if mode in _SUPERVISED_MODES and self._authority is not None:
            authority_m = self._authority_locations()
            release_mps = self._authority.release_speed_mps
        return self._motion.supervise(
            interval=self._interval,
            speed_mps=self._where.speed_mps,
            acceleration_mps2=self._where.acceleration_mps2,
            limit_mps=self._mode_limit_mps(mode),
            authority_m=authority_m,
            release_speed_mps=release_mps,
        )

    # -- internals: output ----------------------------------------------------------------------

    def _output(self, result: SupervisionResult) -> EtcsOutput:
        interval = self._interval
        commands = self._latch.commands
        eoa_chainage_m = eoa_distance_m = svl_distance_m = None
        if self._authority is not None:
            eoa_m, svl_m = self._authority_locations()
            eoa_chainage_m = self.track_map.normalise(eoa_m)
            eoa_distance_m = eoa_m - interval.estimated_front_m
            svl_distance_m = svl_m - interval.max_safe_front_m
        target = result.target
        return EtcsOutput(
            time_s=self._time_s,
            mode=self._mode,
            level=self.level,
            supervision_status=self._latch.status(result.demand.status),
            monitoring=result.monitoring,
            permitted_speed_mps=result.permitted_speed_mps,
            ceiling_speed_mps=result.ceiling_speed_mps,
            target_speed_mps=None if target is None else target.speed_mps,
            target_distance_m=result.target_distance_m,
            release_speed_mps=result.release_speed_mps,
            end_of_authority_m=eoa_chainage_m,
            end_of_authority_distance_m=eoa_distance_m,
            supervised_location_distance_m=svl_distance_m,
            traction_cut=commands.traction_cut,
            service_brake=commands.service_brake,
            emergency_brake=commands.emergency_brake,
            estimated_front_m=self.track_map.normalise(interval.estimated_front_m),
            odometry=interval,
            lrbg_id=self._where.lrbg_id,
            estimated_speed_mps=self._where.speed_mps,
            estimated_acceleration_mps2=self._where.acceleration_mps2,
            wheel_adhesion=self._where.adhesion,
            linking_events=self._take_unreported(),
        )

    def _take_unreported(self) -> tuple[LinkingEvent, ...]:
        events, self._unreported = tuple(self._unreported), []
        return events
