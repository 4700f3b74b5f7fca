"""The mode and the level of :class:`EtcsOnboard`, and the transitions it takes.

:class:`ModeControl` gathers every cycle the conditions of :mod:`onboard.etcs.modes` from the
state of the onboard (the MA and track description, the confidence interval, the commands held,
the requests of the VC and the ATO), takes the transitions they select
(:func:`select_transition`) with what entering a mode implies, applies the level transitions a
balise group announced once the front end reaches them, and answers the requests that change the
mode (start of mission, trip acknowledgement, isolation and insertion, ATO engagement, emergency
stop), refusing those the mode does not allow.
"""

from __future__ import annotations

from onboard.etcs._exceptions import TransitionRefusedError
from onboard.etcs.authority import AuthorityKeeper
from onboard.etcs.balises import LevelTransition
from onboard.etcs.localisation import Localisation
from onboard.etcs.mode_supervision import ModeSupervision
from onboard.etcs.modes import (
    STANDSTILL_MODES,
    ModeChange,
    ModeCondition,
    ModeTransition,
    select_transition,
)
from onboard.etcs.movement_authority import EtcsLevel
from protocol.messages import EtcsMode

__all__ = ["ModeControl"]

_TRANSITIONS_PER_EVALUATION = 4
"""The most transitions one evaluation takes in a row (e.g. TR → PT → SR)."""


class ModeControl:
    """The mode, the level and the one-cycle events that may change the mode.

    Parameters
    ----------
    level : EtcsLevel
        The starting level.
    where : Localisation
        Where the train is: the confidence interval.
    authority : AuthorityKeeper
        The MA in force and the track description.
    supervision : ModeSupervision
        The commands held, and what entering a mode resets there; its train data (the length)
        and national values (D_NVSTFF).
    start_m : float
        The front end's location [m] at start, where staff responsible is measured from.
    """

    def __init__(
        self,
        level: EtcsLevel,
        where: Localisation,
        authority: AuthorityKeeper,
        supervision: ModeSupervision,
        *,
        start_m: float,
    ) -> None:
        self.mode = EtcsMode.SB
        self.level = level
        self.level_transitions: list[LevelTransition] = []
        self.changes: list[ModeChange] = []
        self.events: set[ModeCondition] = set()
        """Conditions that hold for one evaluation or one cycle (a request, a balise group)."""
        self.isolated = False
        self.automatic_driving_requested = False
        self.staff_responsible_start_m = start_m
        self._where = where
        self._authority = authority
        self._supervision = supervision
        self._train = supervision.train
        self._national = supervision.national

    # -- requests -------------------------------------------------------------------------------

    def start_of_mission(self, now_s: float) -> None:
        """Start of mission in SB or PT: FS or OS with an MA on board, SR otherwise."""
        if self.mode not in STANDSTILL_MODES:
            raise TransitionRefusedError(f"start of mission is for SB and PT, not {self.mode}")
        self.event(ModeCondition.START_IN_STAFF_RESPONSIBLE, now_s)

    def acknowledge_trip(self, now_s: float, *, standstill: bool) -> None:
        """The trip acknowledged: TR → PT, at standstill only."""
        if self.mode is not EtcsMode.TR:
            raise TransitionRefusedError(f"no trip to acknowledge in {self.mode}")
        if not standstill:
            raise TransitionRefusedError("a trip is acknowledged at standstill only")
        self.event(ModeCondition.TRIP_ACKNOWLEDGED, now_s)

    def isolate(self, now_s: float) -> None:
        """ETCS isolated (the VC's relay): IS from any mode."""
        self.isolated = True
        self.evaluate(now_s)

    def insert(self, now_s: float) -> None:
        """ETCS inserted again: IS → SB."""
        if not self.isolated:
            raise TransitionRefusedError("ETCS is not isolated")
        self.isolated = False
        self.evaluate(now_s)

    def request_automatic_driving(self, engaged: bool, now_s: float) -> None:
        """ATO engaged (FS → AD when the conditions hold) or disengaged (AD → FS)."""
        self.automatic_driving_requested = engaged
        self.evaluate(now_s)

    def emergency_stop(self, now_s: float) -> None:
        """An unconditional emergency stop from the RBC: trip in SR, FS, OS and AD."""
        self.event(ModeCondition.EMERGENCY_STOP, now_s)

    def event(self, condition: ModeCondition, now_s: float) -> None:
        """A condition that holds for this evaluation only."""
        self.events.add(condition)
        self.evaluate(now_s)
        self.events.discard(condition)

    # -- transitions ----------------------------------------------------------------------------

    def apply_level_transitions(self) -> None:
        """Take the level transitions the estimated front end has reached."""
        front_m = self._where.interval.estimated_front_m
        due = [t for t in self.level_transitions if front_m >= t.location_m]
        for transition in due:
            self.level = transition.level
            self.level_transitions.remove(transition)

    def evaluate(self, now_s: float) -> None:
        """Take the transitions whose conditions hold, one after the other."""
        for _ in range(_TRANSITIONS_PER_EVALUATION):
            transition = select_transition(self.mode, self.conditions(), self.level)
            if transition is None:
                return
            self.enter(transition, now_s)

    def settle(self, now_s: float) -> None:
        """Evaluate, then forget the events of this cycle (a balise group's)."""
        self.evaluate(now_s)
        self.events.clear()

    def conditions(self) -> set[ModeCondition]:
        """The conditions that hold now."""
        conditions = set(self.events)
        conditions.add(ModeCondition.ISOLATED if self.isolated else ModeCondition.INSERTED)
        front = self._where.interval
        authority = self._authority
        if authority.in_force is not None:
            eoa_m, _ = authority.locations()
            if front.min_safe_front_m > eoa_m:
                conditions.add(ModeCondition.END_OF_AUTHORITY_PASSED)
            if authority.described_from(front.estimated_front_m):
                if authority.in_on_sight_area(front.estimated_front_m, self._train.length_m):
                    conditions.add(ModeCondition.ON_SIGHT_AUTHORITY)
                else:
                    conditions.add(ModeCondition.AUTHORITY_AND_TRACK_DESCRIPTION)
        sr_limit_m = self.staff_responsible_start_m + self._national.d_nvstff_m
        if self.mode is EtcsMode.SR and front.min_safe_front_m > sr_limit_m:
            conditions.add(ModeCondition.STAFF_RESPONSIBLE_DISTANCE_PASSED)
        commands = self._supervision.latch.commands
        braking = commands.service_brake or commands.emergency_brake
        if braking:
            conditions.add(ModeCondition.BRAKE_COMMANDED)
        if not self.automatic_driving_requested:
            conditions.add(ModeCondition.AUTOMATIC_DRIVING_DISENGAGED)
        elif not braking and authority.described_from(
            front.min_safe_front_m - self._train.length_m
        ):  # the track description under the whole train
            conditions.add(ModeCondition.AUTOMATIC_DRIVING_ENGAGED)
        return conditions

    def enter(self, transition: ModeTransition, now_s: float) -> None:
        """Take ``transition`` at ``now_s`` [s]."""
        target = transition.target
        self.changes.append(
            ModeChange(time_s=now_s, source=self.mode, target=target, transition=transition)
        )
        self.mode = target
        self.events.discard(transition.condition)
        front_m = self._where.interval.estimated_front_m
        if target in (EtcsMode.TR, EtcsMode.IS):
            self._authority.clear()
            self.automatic_driving_requested = False
            self.events.clear()
        self._supervision.mode_entered(target, front_m)
        if target is EtcsMode.SR:
            self.staff_responsible_start_m = front_m
        if transition.condition is ModeCondition.BRAKE_COMMANDED:
            self.automatic_driving_requested = False
