"""The supervision each mode asks for, the commands latched, and the cycle's output.

:class:`ModeSupervision` is the supervision step of :class:`EtcsOnboard`:

- SB, PT: standstill supervision; moving more than D_NVROLL commands the EB (roll-away
  protection), revoked at standstill.
- SR: CSM and the MRSP's decreases under min(MRSP, V_NVSTFF).
- FS, AD: CSM, TSM of the MRSP's decreases, of the EoA and of the SvL, RSM.
- OS: as FS, with the on-sight area's speed (V_NVONSIGHT by default) as a ceiling.
- TR: EB until the trip is acknowledged at standstill; IS: nothing (the VC supervises).

The speed and distance monitoring itself is :class:`~onboard.etcs._motion.MotionSupervisor`'s
(:mod:`onboard.etcs.supervision`); here the demand of the mode and of a linking reaction's
service brake is latched (:class:`InterventionLatch`), the interventions are counted, and the
cycle's :class:`EtcsOutput` is assembled.
"""

from __future__ import annotations

import math

from onboard.etcs._motion import MotionSupervisor
from onboard.etcs.authority import AuthorityKeeper
from onboard.etcs.braking import BrakingModel
from onboard.etcs.linking import LinkingEvent
from onboard.etcs.localisation import Localisation
from onboard.etcs.modes import STANDSTILL_MODES, SUPERVISED_MODES
from onboard.etcs.movement_authority import EtcsLevel
from onboard.etcs.output import EtcsOutput
from onboard.etcs.supervision import (
    Demand,
    InterventionLatch,
    Monitoring,
    SupervisionResult,
)
from protocol.messages import EtcsMode, SupervisionStatus
from trackdb import TrackMap

__all__ = ["STANDSTILL_SPEED_MPS", "ModeSupervision"]

STANDSTILL_SPEED_MPS = 0.05
"""At or below this speed [m/s] the train is at standstill."""


class ModeSupervision:
    """Supervises the train for its mode and holds the commands between cycles.

    Parameters
    ----------
    track_map : TrackMap
        The line: MRSP, gradients, its length on a ring.
    braking : BrakingModel
        The train's braking model, with its train data, national and fixed values.
    where : Localisation
        Where the train is: the confidence interval, the speed and A_est.
    authority : AuthorityKeeper
        The MA in force and the track description.
    roll_reference_m : float
        Where [m] the roll-away protection measures from at start.
    """

    def __init__(
        self,
        track_map: TrackMap,
        braking: BrakingModel,
        where: Localisation,
        authority: AuthorityKeeper,
        *,
        roll_reference_m: float,
    ) -> None:
        self.track_map = track_map
        self.train, self.national = braking.train, braking.national
        self.where = where
        self.authority = authority
        self.latch = InterventionLatch(
            release_at_standstill=self.national.emergency_brake_release_at_standstill
        )
        self.motion = MotionSupervisor(track_map, braking)
        self.linking_brake = False
        """A linking reaction's service brake, held until standstill."""
        self.roll_reference_m = roll_reference_m
        self.service_brake_interventions = 0
        self.emergency_brake_interventions = 0
        self.result: SupervisionResult = self.idle_result(EtcsMode.SB, 0.0)

    def use_line(self, track_map: TrackMap) -> None:
        """New track data of the same line: the targets are rebuilt on them."""
        self.track_map = track_map
        self.motion.use_line(track_map)

    @property
    def standstill(self) -> bool:
        """Whether the last speed given was a standstill."""
        return self.where.speed_mps <= STANDSTILL_SPEED_MPS

    def mode_entered(self, target: EtcsMode, front_m: float) -> None:
        """The mode became ``target``, the estimated front end at ``front_m`` [m]."""
        if target in (EtcsMode.TR, EtcsMode.IS):
            self.linking_brake = False
        if target is EtcsMode.IS:
            self.latch.reset()
        if target in STANDSTILL_MODES:
            self.roll_reference_m = front_m

    def idle_result(self, mode: EtcsMode, permitted_mps: float) -> SupervisionResult:
        """A result that demands nothing, at a permitted speed [m/s]."""
        return SupervisionResult(
            demand=Demand(),
            monitoring=Monitoring.CEILING_SPEED,
            permitted_speed_mps=permitted_mps,
            ceiling_speed_mps=permitted_mps,
            target=None,
            target_distance_m=None,
            release_speed_mps=None,
            ceiling_intervention_mps=math.inf if mode is EtcsMode.IS else permitted_mps,
        )

    def supervise(self, mode: EtcsMode) -> SupervisionResult:
        """Supervise this cycle in ``mode`` and latch the commands."""
        if mode is EtcsMode.IS:
            self.latch.reset()
            result = self.idle_result(mode, self.motion.ceiling_mps(self.where.interval, math.inf))
        elif mode in SUPERVISED_MODES or mode is EtcsMode.SR:
            result = self._supervise_motion(mode)
            self._latch_commands(self._with_linking_brake(result.demand), forced=False)
        else:
            forced = mode is EtcsMode.TR
            if mode in STANDSTILL_MODES:
                if self.standstill:
                    self.roll_reference_m = self.where.interval.estimated_front_m
                moved_m = abs(self.where.interval.estimated_front_m - self.roll_reference_m)
                forced = moved_m > self.national.d_nvroll_m
            result = self.idle_result(mode, 0.0)
            self._latch_commands(result.demand, forced=forced)
        self.result = result
        return result

    def _with_linking_brake(self, demand: Demand) -> Demand:
        """The linking reaction's service brake (the EB without one), held to standstill."""
        if self.linking_brake and self.standstill:
            self.linking_brake = False
        if not self.linking_brake:
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
        before = self.latch.commands
        after = self.latch.update(demand, standstill=self.standstill, forced_emergency_brake=forced)
        self.service_brake_interventions += after.service_brake and not before.service_brake
        self.emergency_brake_interventions += after.emergency_brake and not before.emergency_brake

    def _mode_limit_mps(self, mode: EtcsMode) -> float:
        limit_mps = self.train.max_speed_mps
        if mode is EtcsMode.SR:
            limit_mps = min(limit_mps, self.national.v_nvstff_mps)
        authority = self.authority.in_force
        if mode is EtcsMode.OS and authority is not None:
            area = authority.authority.on_sight
            speed_mps = None if area is None else area.speed_mps
            limit_mps = min(limit_mps, speed_mps or self.national.v_nvonsight_mps)
        return limit_mps

    def _supervise_motion(self, mode: EtcsMode) -> SupervisionResult:
        authority_m = release_mps = None
        authority = self.authority.in_force
        if mode in SUPERVISED_MODES and authority is not None:
            authority_m = self.authority.locations()
            release_mps = authority.release_speed_mps
        return self.motion.supervise(
            interval=self.where.interval,
            speed_mps=self.where.speed_mps,
            acceleration_mps2=self.where.acceleration_mps2,
            limit_mps=self._mode_limit_mps(mode),
            authority_m=authority_m,
            release_speed_mps=release_mps,
        )

    def output(
        self,
        time_s: float,
        mode: EtcsMode,
        level: EtcsLevel,
        linking_events: tuple[LinkingEvent, ...],
    ) -> EtcsOutput:
        """The cycle's outcome at ``time_s`` [s], from the last result and the commands held."""
        where, result = self.where, self.result
        interval = where.interval
        commands = self.latch.commands
        eoa_chainage_m = eoa_distance_m = svl_distance_m = None
        if self.authority.in_force is not None:
            eoa_m, svl_m = self.authority.locations()
            eoa_chainage_m = self.track_map.normalise(eoa_m)
            eoa_distance_m = eoa_m - interval.estimated_front_m
            svl_distance_m = svl_m - interval.max_safe_front_m
        target = result.target
        return EtcsOutput(
            time_s=time_s,
            mode=mode,
            level=level,
            supervision_status=self.latch.status(result.demand.status),
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
            lrbg_id=where.lrbg_id,
            estimated_speed_mps=where.speed_mps,
            estimated_acceleration_mps2=where.acceleration_mps2,
            wheel_adhesion=where.adhesion,
            linking_events=linking_events,
        )
