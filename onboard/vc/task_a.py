"""Task A, the request composer (seed 004 §2.4, Table 2; DOMAIN.md §7.2): every 40 ms, last.

At each release Task A reads the latest statuses of Tasks B and C, moves its FSM (what the VC
needs from the operator now, :mod:`onboard.vc.fsm`), sets the six request flags and sends the
:class:`~onboard.vc.messages.VcRequest`, with a copy to Task B. When each flag is up (Table 2 is
not in our copy of the seed; these are our triggers, docs/vc.md):

===========================  ================================================================
section                      flag up
===========================  ================================================================
ATO Vitality                 in every request, with a new number (pulsed)
EB Release Confirmation      in every request until System Decay, with a new number (pulsed)
Operator Vigilance           every ``vigilance_period_s`` from power-up, until confirmed
ETCS Isolation Confirmation  at standstill with ETCS inserted, until System Decay
ETCS Insertion Confirmation  at standstill with ETCS isolated, until System Decay
EB Rearm Confirmation        in REARM_PENDING: EB applied at standstill, no hazard
===========================  ================================================================
"""

from __future__ import annotations

from onboard.vc.config import TIME_TOLERANCE_S, VcConfig
from onboard.vc.fsm import (
    TASK_A_TRANSITIONS,
    BrakeState,
    EtcsState,
    StateMachine,
    TaskAState,
    Trigger,
)
from onboard.vc.ipc import ActuationStatus, Mailbox, MessageQueue, SupervisionStatus
from onboard.vc.link import FaultyLink
from onboard.vc.messages import (
    PULSED_SECTIONS,
    SECTIONS,
    DecayReason,
    Notification,
    Section,
    SectionRequest,
    VcRequest,
)

__all__ = ["TaskA"]


class TaskA:
    """Task A of one VC.

    Parameters
    ----------
    request_link
        The link's VC → ATO-OB direction, written here only.
    requests_sent
        Where Task B finds a copy of each request sent.
    supervision, actuation
        Tasks B's and C's latest statuses.
    """

    def __init__(
        self,
        config: VcConfig,
        *,
        request_link: FaultyLink[VcRequest],
        requests_sent: MessageQueue[VcRequest],
        supervision: Mailbox[SupervisionStatus],
        actuation: Mailbox[ActuationStatus],
        start_s: float = 0.0,
    ) -> None:
        self.config = config
        self.fsm = StateMachine(TASK_A_TRANSITIONS, TaskAState.BRAKED)
        self.last_request: VcRequest | None = None
        self._request_link = request_link
        self._requests_sent = requests_sent
        self._supervision = supervision
        self._actuation = actuation
        self._numbers = dict.fromkeys(SECTIONS, 0)
        self._flags = dict.fromkeys(SECTIONS, False)
        self._next_vigilance_s = start_s
        self._vigilance_raised_s = start_s

    def _triggers(self, b: SupervisionStatus | None, c: ActuationStatus | None) -> set[Trigger]:
        triggers: set[Trigger] = set()
        if (b is not None and b.system_decay) or (c is not None and c.system_decay):
            triggers.add(Trigger.SYSTEM_DECAY)
        if b is None or c is None:
            return triggers
        brake = c.brake_state
        if brake is BrakeState.RELEASED:
            triggers.add(Trigger.EB_RELEASED)
        else:
            triggers.add(Trigger.EB_APPLIED)
        hazard = b.eb_flag or bool(b.live_conditions)
        if brake is BrakeState.STANDSTILL and b.standstill and not hazard:
            triggers.add(Trigger.REARM_POSSIBLE)
        rearm = Section.EB_REARM_CONFIRMATION
        attempt_failed = (
            brake is BrakeState.STANDSTILL
            and self._flags[rearm]
            and c.consumed_rearm_number == self._numbers[rearm]
        )
        if brake is BrakeState.BRAKING or hazard or attempt_failed:
            triggers.add(Trigger.REARM_ABORTED)
        return triggers

    def _set(self, section: Section, flag: bool) -> None:
        if flag and (section in PULSED_SECTIONS or not self._flags[section]):
            self._numbers[section] = (self._numbers[section] + 1) % self.config.sequence_modulo
        self._flags[section] = flag

    def _vigilance_flag(self, now_s: float, b: SupervisionStatus | None, decayed: bool) -> bool:
        section = Section.OPERATOR_VIGILANCE
        if decayed:
            return False
        if self._flags[section]:
            confirmed = b is not None and b.vigilance_confirmed_number == self._numbers[section]
            if confirmed:
                self._next_vigilance_s = self._vigilance_raised_s + self.config.vigilance_period_s
            return not confirmed
        if now_s + TIME_TOLERANCE_S >= self._next_vigilance_s:
            self._vigilance_raised_s = now_s
            return True
        return False

    def step(self, now_s: float) -> VcRequest:
        """Compose and send the request of ``now_s``; returns it."""
        b, c = self._supervision.read(), self._actuation.read()
        self.fsm.fire(self._triggers(b, c), now_s)
        state = self.fsm.state
        decayed = state is TaskAState.DECAYED
        standstill = b is not None and b.standstill
        etcs = c.etcs_state if c is not None else None
        self._set(Section.ATO_VITALITY, True)
        self._set(Section.EB_RELEASE_CONFIRMATION, not decayed)
        self._set(Section.OPERATOR_VIGILANCE, self._vigilance_flag(now_s, b, decayed))
        self._set(
            Section.ETCS_ISOLATION_CONFIRMATION,
            not decayed and standstill and etcs is EtcsState.INSERTED,
        )
        self._set(
            Section.ETCS_INSERTION_CONFIRMATION,
            not decayed and standstill and etcs is EtcsState.ISOLATED,
        )
        self._set(Section.EB_REARM_CONFIRMATION, state is TaskAState.REARM_PENDING)
        request = VcRequest(
            sent_s=now_s,
            sections=tuple(SectionRequest(self._numbers[s], self._flags[s]) for s in SECTIONS),
            estimated_speed_mps=b.speed_mps if b is not None else None,
            estimated_position_m=b.position_m if b is not None else None,
            last_balise_header=b.last_balise_header if b is not None else None,
            notifications=self._notifications(b, c),
            eb_conditions=tuple(sorted(b.eb_conditions)) if b is not None else (),
            decay_reasons=_decay_reasons(b, c),
        )
        self._request_link.send(request, now_s)
        self._requests_sent.put(request)
        self.last_request = request
        return request

    def _notifications(
        self, b: SupervisionStatus | None, c: ActuationStatus | None
    ) -> tuple[Notification, ...]:
        found: list[Notification] = []
        if c is None or c.brake_state is not BrakeState.RELEASED:
            found.append(Notification.EB_APPLIED)
        if self.fsm.state is TaskAState.DECAYED:
            found.append(Notification.SYSTEM_DECAY)
        if b is not None:
            if b.etcs_isolated:
                found.append(Notification.ETCS_ISOLATED)
            if not b.odometry_efficient:
                found.append(Notification.ODOMETRY_NOT_EFFICIENT)
            if b.standstill:
                found.append(Notification.STANDSTILL)
        if self._flags[Section.EB_REARM_CONFIRMATION]:
            found.append(Notification.REARM_REQUESTED)
        return tuple(found)


def _decay_reasons(
    b: SupervisionStatus | None, c: ActuationStatus | None
) -> tuple[DecayReason, ...]:
    reasons: list[DecayReason] = list(b.decay_reasons) if b is not None else []
    reasons += [r for r in (c.decay_reasons if c is not None else ()) if r not in reasons]
    return tuple(reasons)
