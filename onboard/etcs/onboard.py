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

:class:`EtcsOnboard` checks the inputs and the time and runs these steps; its parts hold the
state and do the work: :class:`~onboard.etcs.localisation.Localisation` (where the train is),
:class:`~onboard.etcs.authority.AuthorityKeeper` (the MA and track description),
:class:`~onboard.etcs.mode_control.ModeControl` (the mode and the level),
:class:`~onboard.etcs.mode_supervision.ModeSupervision` (the supervision, the commands, the
output) and :class:`~onboard.etcs.balise_intake.BaliseIntake` (the groups read, the linking).

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

from onboard.etcs._exceptions import EtcsInputError
from onboard.etcs.authority import AuthorityKeeper
from onboard.etcs.balise_intake import BaliseIntake
from onboard.etcs.balises import BaliseGroupReading
from onboard.etcs.braking import BrakingModel
from onboard.etcs.linking import LinkingEvent
from onboard.etcs.localisation import Localisation, OdometerPoint
from onboard.etcs.mode_control import ModeControl
from onboard.etcs.mode_supervision import STANDSTILL_SPEED_MPS, ModeSupervision
from onboard.etcs.modes import ModeChange
from onboard.etcs.movement_authority import (
    AuthorityInForce,
    EtcsLevel,
    MaChange,
    MovementAuthority,
)
from onboard.etcs.odometer import Odometer, OdometerParameters
from onboard.etcs.odometry import ConfidenceInterval, OdometryAccuracy
from onboard.etcs.output import EtcsOutput
from onboard.etcs.values import (
    FIXED_VALUES,
    NATIONAL_DEFAULTS,
    URV_TRAIN_DATA,
    FixedValues,
    NationalValues,
    TrainData,
)
from onboard.plant.readings import BaliseDetection, WheelReading
from protocol.messages import EtcsMode
from trackdb import BaliseGroup, TrackMap

__all__ = ["STANDSTILL_SPEED_MPS", "EtcsOnboard", "EtcsOutput"]


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
        self.read_balise_groups = odometer is None and read_balise_groups is not False
        self.odometer = None if odometer is None else Odometer(odometer, start_s=start_s)
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
        self._authority = AuthorityKeeper()
        self._supervision = ModeSupervision(
            track_map, self.braking, self._where, self._authority, roll_reference_m=position_m
        )
        self._modes = ModeControl(
            EtcsLevel(track_map.line.etcs_level) if level is None else level,
            self._where,
            self._authority,
            self._supervision,
            start_m=position_m,
        )
        self._balises = BaliseIntake(
            self._where, self._authority, self._modes, self._supervision, national
        )
        # The records the callers read, the very lists the parts append to.
        self.mode_changes: list[ModeChange] = self._modes.changes
        self.linking_events: list[LinkingEvent] = self._balises.linking_events
        self.output = self._output()

    def use_line(self, track_map: TrackMap) -> None:
        """New track data of the same line, taken at standstill: odometry, MA, mode kept."""
        self.track_map = self._where.track_map = track_map
        self._supervision.use_line(track_map)

    # -- state ----------------------------------------------------------------------------------

    @property
    def mode(self) -> EtcsMode:
        """The current mode."""
        return self._modes.mode

    @property
    def level(self) -> EtcsLevel:
        """The current level."""
        return self._modes.level

    @property
    def movement_authority(self) -> AuthorityInForce | None:
        """The MA in force, in track locations [m]."""
        return self._authority.in_force

    @property
    def odometry(self) -> ConfidenceInterval:
        """The confidence interval after the last cycle or balise group."""
        return self._where.interval

    @property
    def last_balise_reading(self) -> BaliseGroupReading | None:
        """The last group read; its ``header`` is the telegram header the VC forwards."""
        return self._balises.last_reading

    @property
    def service_brake_interventions(self) -> int:
        """Rising edges of the service-brake command so far."""
        return self._supervision.service_brake_interventions

    @property
    def emergency_brake_interventions(self) -> int:
        """Rising edges of the emergency-brake command so far."""
        return self._supervision.emergency_brake_interventions

    def intervention_speed_mps(self) -> float:
        """The speed at which the last cycle's supervision would intervene [m/s]; inf when
        nothing is supervised (IS). Computed on demand: a status value."""
        return self._supervision.result.intervention_speed_mps()

    @property
    def standstill(self) -> bool:
        """Whether the last speed given was a standstill."""
        return self._supervision.standstill

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
        _check_motion(position_m, speed_mps, acceleration_mps2)
        previous_m = self._where.odometer_m
        self._where.move(position_m, speed_mps, acceleration_mps2)
        if self.read_balise_groups:
            self._balises.read_passed(previous_m, now_s)
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
        detections = _in_time_order(balises)
        self._where.sense(odometer, wheels)
        self._balises.read_detected(odometer, detections, now_s)
        return self._cycle(now_s)

    def _cycle(self, now_s: float) -> EtcsOutput:
        """The cycle once the odometer has moved and the groups are read."""
        modes = self._modes
        self._where.update()
        if modes.mode is not EtcsMode.IS:
            self._balises.check_windows(now_s)
        modes.apply_level_transitions()
        self._authority.update(now_s, self._where.interval)
        modes.settle(now_s)
        self._supervision.supervise(modes.mode)
        modes.evaluate(now_s)
        self.output = self._output()
        return self.output

    def _output(self) -> EtcsOutput:
        modes = self._modes
        linking_events = self._balises.take_unreported()
        return self._supervision.output(self._time_s, modes.mode, modes.level, linking_events)

    # -- requests -------------------------------------------------------------------------------

    def start_of_mission(self, now_s: float) -> None:
        """Start of mission in SB or PT: FS or OS with an MA on board, SR otherwise."""
        self._check_time(now_s)
        self._modes.start_of_mission(now_s)

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
        if track_description_m is not None:
            _check_track_description(track_description_m)
        if self._modes.mode in (EtcsMode.TR, EtcsMode.IS):
            return MaChange.REJECTED
        change = self._authority.accept_with_track_description(
            authority,
            now_s,
            reference_location_m=self._where.locate_span(
                authority.reference_m, authority.end_of_authority_m
            ),
            track_description_m=track_description_m,
        )
        self._modes.evaluate(now_s)
        return change

    def pass_balise_group(
        self, group: BaliseGroup, now_s: float, *, position_m: float | None = None
    ) -> BaliseGroupReading:
        """The front end passed ``group`` when the odometer read ``position_m`` (chainage)."""
        self._refuse_on_sensors("pass_balise_group")
        self._check_time(now_s)
        where = self._where
        odometer_m = where.odometer_m if position_m is None else where.unwrap(position_m)
        reading = self._balises.read(
            group, now_s, time_s=now_s, at=OdometerPoint(odometer_m=odometer_m)
        )
        where.update()
        self._modes.settle(now_s)
        return reading

    def acknowledge_trip(self, now_s: float) -> None:
        """The trip acknowledged: TR → PT, at standstill only."""
        self._check_time(now_s)
        self._modes.acknowledge_trip(now_s, standstill=self.standstill)

    @property
    def isolated(self) -> bool:
        """The ETCS-OB's power is cut (by the VC's relay): mode IS."""
        return self._modes.isolated

    def isolate(self, now_s: float) -> None:
        """ETCS isolated (the VC's relay): IS from any mode, commands dropped."""
        self._check_time(now_s)
        self._modes.isolate(now_s)

    def insert(self, now_s: float) -> None:
        """ETCS inserted again: IS → SB."""
        self._check_time(now_s)
        self._modes.insert(now_s)

    def request_automatic_driving(self, engaged: bool, now_s: float) -> None:
        """ATO engaged (FS → AD when the conditions hold) or disengaged (AD → FS)."""
        self._check_time(now_s)
        self._modes.request_automatic_driving(engaged, now_s)

    def emergency_stop(self, now_s: float) -> None:
        """An unconditional emergency stop from the RBC: trip in SR, FS, OS and AD."""
        self._check_time(now_s)
        self._modes.emergency_stop(now_s)

    # -- internals: inputs -----------------------------------------------------------------------

    def _refuse_on_sensors(self, call: str) -> None:
        if self.odometer is not None:
            raise EtcsInputError(f"{call} gives motion; this onboard runs on its sensors")

    def _check_time(self, now_s: float) -> None:
        if not math.isfinite(now_s) or now_s < self._time_s:
            raise EtcsInputError(f"time {now_s} s is not finite or before {self._time_s} s")
        self._time_s = now_s


def _check_motion(position_m: float, speed_mps: float, acceleration_mps2: float) -> None:
    """Refuse a given motion that is not finite, or runs backwards."""
    if not (math.isfinite(position_m) and math.isfinite(acceleration_mps2)):
        raise EtcsInputError("position and acceleration must be finite")
    if not (math.isfinite(speed_mps) and speed_mps >= 0.0):
        raise EtcsInputError(f"speed {speed_mps} m/s must be finite and ≥ 0")


def _in_time_order(balises: Sequence[BaliseDetection]) -> list[BaliseDetection]:
    """The detections sorted by time; refused if a time is not finite."""
    detections = sorted(balises, key=lambda detection: detection.time_s)
    if not all(math.isfinite(detection.time_s) for detection in detections):
        raise EtcsInputError("balise detection times must be finite")
    return detections


def _check_track_description(track_description_m: float) -> None:
    """Refuse a track description's length [m] that is not positive and finite."""
    if not (math.isfinite(track_description_m) and track_description_m > 0.0):
        raise EtcsInputError("a track description needs a positive finite length")
