"""Task B, the supervisor (seed 004 §2.4, Table 3; DOMAIN.md §7.2): every 2 ms, first of all.

Each cycle Task B

1. takes the requests Task A sent (to know what each response must carry);
2. checks the ATO-OB's responses: each must match an outstanding request by its ATO Vitality
   number, arrive within the 40 ms + 4 ms window, carry exactly the expected sequence numbers
   (:func:`~onboard.vc.messages.expected_response_number`) and the status OK; it reads the
   operator's answers (EB request, vigilance, ETCS and rearm confirmations) from valid
   responses only (:class:`~onboard.vc.exchange_check.ExchangeCheck` keeps the
   outstanding requests and the confirmations);
3. checks the deadlines: a request not answered within the window (vitality), a vigilance
   request not confirmed within its timeout;
4. updates the tachometer odometry (:mod:`onboard.vc.odometry`) and re-reads the EB and ETCS
   digital inputs and the BTM;
5. raises the EB flag on the six conditions of seed 004, System Decay on 2, 3 and 4, and
   publishes a :class:`~onboard.vc.ipc.SupervisionStatus` for Tasks C and A.

The flag stays up until the hazard has gone with the train at standstill and the EB applied
(row B3); the EB itself stays applied until Task C rearms it on the operator's confirmation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from onboard.etcs.balises import TelegramHeader
from onboard.vc.config import VcConfig
from onboard.vc.exchange_check import ExchangeCheck, Findings
from onboard.vc.fsm import (
    TASK_B_TRANSITIONS,
    BrakeState,
    StateMachine,
    TaskBState,
    Trigger,
)
from onboard.vc.hardware import TachometerFrame
from onboard.vc.ipc import (
    ActuationStatus,
    Delivery,
    Mailbox,
    MessageQueue,
    SupervisionStatus,
    VcEvent,
    VcEventKind,
)
from onboard.vc.link import FaultyLink
from onboard.vc.messages import (
    DECAY_CONDITIONS,
    AtoObResponse,
    DecayReason,
    EbCondition,
    Section,
    VcRequest,
)
from onboard.vc.odometry import OdometryEstimate, TachometerOdometry
from onboard.vc.quiet import QuietCycles

__all__ = ["TaskB"]

_C = EbCondition


class TaskB:
    """Task B of one VC.

    Parameters
    ----------
    response_link
        The link's ATO-OB → VC direction, read here only.
    requests_sent
        Task A's copies of the requests it sent.
    tachometer_frames, balise_telegrams
        The odometry board's frames and the BTM's telegram headers, with their arrival.
    fused_speeds
        The sensor-fusion speed, read when ``config.fused_speed_supervision`` is set.
    read_eb_released, read_etcs_inserted
        The EB and ETCS digital inputs.
    actuation
        Task C's latest status.
    status
        Where Task B posts its own (a new mailbox by default).
    """

    def __init__(
        self,
        config: VcConfig,
        *,
        response_link: FaultyLink[AtoObResponse],
        requests_sent: MessageQueue[VcRequest],
        tachometer_frames: MessageQueue[Delivery[TachometerFrame]],
        balise_telegrams: MessageQueue[Delivery[TelegramHeader]],
        fused_speeds: MessageQueue[Delivery[float]] | None = None,
        read_eb_released: Callable[[float], bool],
        read_etcs_inserted: Callable[[float], bool],
        actuation: Mailbox[ActuationStatus],
        status: Mailbox[SupervisionStatus] | None = None,
        start_s: float = 0.0,
    ) -> None:
        self.config = config
        self.status = status if status is not None else Mailbox[SupervisionStatus]()
        self.fsm = StateMachine(TASK_B_TRANSITIONS, TaskBState.MONITORING)
        self.events: list[VcEvent] = []
        self._response_link = response_link
        self._requests_sent = requests_sent
        self._tachometer_frames = tachometer_frames
        self._balise_telegrams = balise_telegrams
        self._fused_speeds = fused_speeds
        queues = (requests_sent, tachometer_frames, balise_telegrams, fused_speeds)
        self.input_queues: tuple[MessageQueue[Any], ...] = tuple(q for q in queues if q is not None)
        """The queues a cycle reads: each put is an input (:mod:`onboard.vc.tick`)."""
        self._fused: Delivery[float] | None = None
        self._read_eb_released = read_eb_released
        self._read_etcs_inserted = read_etcs_inserted
        self._actuation = actuation
        self._odometry = odometry = TachometerOdometry(config, start_s=start_s)
        self._exchange = exchange = ExchangeCheck(config)
        self._limits_s = lambda: [*exchange.thresholds_s(), odometry.timeout_threshold_s()]
        self._isolated_since_s: float | None = None
        self._previous_live: frozenset[EbCondition] = frozenset()
        self._eb_conditions: set[EbCondition] = set()
        self._decay_reasons: list[DecayReason] = []
        # What the status carries of the two: rebuilt only when they change (reasons are only
        # ever appended), not in every 2 ms cycle.
        self._eb_conditions_published: frozenset[EbCondition] = frozenset()
        self._decay_reasons_published: tuple[DecayReason, ...] = ()
        self._last_balise_header: TelegramHeader | None = None
        self._found = Findings()
        """The conditions and decay reasons found this cycle, with their evidence time."""
        self.quiet = QuietCycles()
        """Skips the cycles that cannot change anything (lockstep only: :mod:`onboard.vc.quiet`)."""
        # What the last full cycle read, for the quiet cycles' check.
        self._took_input = False
        self._status: SupervisionStatus | None = None
        self._read_inserted = True
        self._read_released = False
        self._read_brake_state: BrakeState | None = None
        self._fused_stale = True

    # -- odometry conditions ---------------------------------------------------------------

    def _check_isolated_odometry(self, now_s: float, odometry: OdometryEstimate) -> bool:
        isolated = not self._read_etcs_inserted(now_s)
        if not isolated:
            self._isolated_since_s = None
            return False
        if self._isolated_since_s is None:
            self._isolated_since_s = now_s
        since_s = self._isolated_since_s
        limit = self.config.speed_limit_etcs_isolated_mps
        fused = self._fresh_fused_speed(now_s)
        if not odometry.efficient:
            evidence_s = max(since_s, odometry.not_efficient_since_s or since_s)
            self._found.note(_C.ODOMETRY_NOT_EFFICIENT, evidence_s)
        elif (odometry.speed_mps or 0.0) > limit:
            evidence_s = max(since_s, odometry.speed_updated_s or since_s)
            self._found.note(_C.OVERSPEED_ETCS_ISOLATED, evidence_s)
        elif fused is not None and fused.message + self.config.fused_speed_margin_mps > limit:
            self._found.note(_C.OVERSPEED_ETCS_ISOLATED, max(since_s, fused.arrived_s))
        return True

    def _fresh_fused_speed(self, now_s: float) -> Delivery[float] | None:
        """The latest fused speed, if the option is on and it is recent enough."""
        if self._fused_speeds is None or not self.config.fused_speed_supervision:
            return None
        arrived = self._fused_speeds.take_all()
        if arrived:
            self._fused = arrived[-1]
            self._took_input = True
        fused = self._fused
        if fused is None or now_s - fused.arrived_s > self.config.fused_speed_timeout_s:
            return None
        return fused

    # -- the cycle -------------------------------------------------------------------------

    def step(self, now_s: float) -> SupervisionStatus:
        """One cycle at ``now_s``; returns (and posts) the status."""
        quiet, last = self.quiet, self._status
        if quiet.enabled and now_s <= quiet.until_s and last and self._quiet_inputs(now_s):
            quiet.skipped += 1
            status = SupervisionStatus._make((now_s, *last[1:]))  # a third of _replace's time
            self.status.post(status)
            return status
        found = self._found = Findings()
        exchange = self._exchange
        requests = self._requests_sent.take_all()
        for request in requests:
            exchange.register(request)
        responses = self._response_link.receive(now_s)
        for delivery in responses:
            exchange.check_response(delivery, now_s, found)
        exchange.check_deadlines(now_s, found)
        frames = self._tachometer_frames.take_all()
        odometry = self._odometry.update(now_s, frames)
        self._took_input = bool(requests or responses or frames)
        isolated = self._check_isolated_odometry(now_s, odometry)
        headers = self._balise_telegrams.take_all()
        if headers:
            self._last_balise_header = headers[-1].message
            self._took_input = True
        self._record(now_s)
        self._transition(now_s, odometry)
        status = self._publish(now_s, odometry, isolated)
        if quiet.enabled:
            self._note_full_cycle(now_s, status)
        return status

    # -- quiet cycles (lockstep) -----------------------------------------------------------

    def _quiet_inputs(self, now_s: float) -> bool:
        """Every input the cycle would read at ``now_s`` is as the last full cycle read it."""
        if (
            self._requests_sent
            or self._tachometer_frames
            or self._balise_telegrams
            or self._response_link.arrived_by(now_s)
        ):
            return False
        if self._read_etcs_inserted(now_s) is not self._read_inserted:
            return False
        if self._read_eb_released(now_s) is not self._read_released:
            return False
        actuation = self._actuation.read()
        if (actuation.brake_state if actuation else None) is not self._read_brake_state:
            return False
        return self._fused_quiet(now_s)

    def quiet_horizon_s(self) -> float:
        """Until when [s] cycles stay quiet with no new input (−inf: the next may not be)."""
        horizon = self.quiet.until_s  # −inf unless enabled and the last full cycle was fixed
        if horizon == -math.inf or self._status is None or any(map(len, self.input_queues)):
            return -math.inf
        fused = self._fused
        supervised = self._fused_speeds is not None and self.config.fused_speed_supervision
        if supervised and fused is not None and not self._fused_stale:
            horizon = min(horizon, fused.arrived_s + self.config.fused_speed_timeout_s)
        return horizon

    def _fused_quiet(self, now_s: float) -> bool:
        if self._fused_speeds is None or not self.config.fused_speed_supervision:
            return True
        if self._fused_speeds and not self._read_inserted:
            return False  # isolated: the cycle would take the new fused speeds
        fused = self._fused
        stale = fused is None or now_s - fused.arrived_s > self.config.fused_speed_timeout_s
        return stale is self._fused_stale

    def _note_full_cycle(self, now_s: float, status: SupervisionStatus) -> None:
        self._status = status
        self._read_inserted = not status.etcs_isolated
        self._read_released = status.eb_released
        actuation = self._actuation.read()
        self._read_brake_state = actuation.brake_state if actuation else None
        fused = self._fused
        self._fused_stale = (
            fused is None or now_s - fused.arrived_s > self.config.fused_speed_timeout_s
        )
        self.quiet.after_full_cycle(
            now_s, self._fingerprint(status), took_input=self._took_input, thresholds=self._limits_s
        )

    def _fingerprint(self, status: SupervisionStatus) -> tuple[object, ...]:
        """Every piece of state a cycle can change, and its status but for the time."""
        return (
            status[1:],
            self.fsm.state,
            len(self.fsm.transitions),
            len(self.events),
            self._fused,
            self._odometry.state_key(),
            self._exchange.state_key(),
            self._isolated_since_s,
            self._previous_live,
            frozenset(self._eb_conditions),
            len(self._decay_reasons),
            self._last_balise_header,
        )

    def _record(self, now_s: float) -> None:
        found = self._found
        if not (found.conditions or found.decays or self._previous_live):
            return  # a quiet cycle after a quiet one: no event, and nothing is live
        live = frozenset(found.conditions)
        for condition in sorted(live - self._previous_live):
            self.events.append(
                VcEvent(
                    time_s=now_s,
                    task="B",
                    kind=VcEventKind.EB_CONDITION,
                    detail=f"{int(condition)} {condition.name.lower()}",
                    evidence_s=found.conditions[condition],
                )
            )
        for reason, evidence_s in found.decays:
            if reason not in self._decay_reasons:
                if not self._decay_reasons:
                    self.events.append(
                        VcEvent(
                            time_s=now_s,
                            task="B",
                            kind=VcEventKind.SYSTEM_DECAY,
                            detail=reason.value,
                            evidence_s=evidence_s,
                        )
                    )
                self._decay_reasons.append(reason)
        self._previous_live = live

    def _transition(self, now_s: float, odometry: OdometryEstimate) -> None:
        live = self._previous_live
        triggers: set[Trigger] = set()
        if live & DECAY_CONDITIONS:
            triggers.add(Trigger.DECAY_CONDITION)
        if live:
            triggers.add(Trigger.EB_CONDITION)
        actuation = self._actuation.read()
        if (
            not live
            and odometry.standstill
            and actuation is not None
            and actuation.brake_state is BrakeState.STANDSTILL
        ):
            triggers.add(Trigger.HAZARD_CLEARED_AT_STANDSTILL)
        rule = self.fsm.fire(triggers, now_s)
        if rule is not None and rule.target is TaskBState.MONITORING and self._eb_conditions:
            self._eb_conditions.clear()
            self._eb_conditions_published = frozenset()
        if self.fsm.state is not TaskBState.MONITORING and not live <= self._eb_conditions:
            self._eb_conditions |= live
            self._eb_conditions_published = frozenset(self._eb_conditions)

    def _publish(
        self, now_s: float, odometry: OdometryEstimate, isolated: bool
    ) -> SupervisionStatus:
        number = self._exchange.confirmed_number
        state = self.fsm.state
        decay_reasons = self._decay_reasons
        if len(decay_reasons) != len(self._decay_reasons_published):
            self._decay_reasons_published = tuple(decay_reasons)
        status = SupervisionStatus(
            time_s=now_s,
            state=state,
            eb_flag=state is not TaskBState.MONITORING,
            eb_conditions=self._eb_conditions_published,
            live_conditions=self._previous_live,
            system_decay=state is TaskBState.DECAYED,
            decay_reasons=self._decay_reasons_published,
            standstill=odometry.standstill,
            odometry_efficient=odometry.efficient,
            speed_mps=odometry.speed_mps,
            position_m=odometry.position_m,
            etcs_isolated=isolated,
            eb_released=self._read_eb_released(now_s),
            vigilance_confirmed_number=number(Section.OPERATOR_VIGILANCE),
            etcs_isolation_confirmed_number=number(Section.ETCS_ISOLATION_CONFIRMATION),
            etcs_insertion_confirmed_number=number(Section.ETCS_INSERTION_CONFIRMATION),
            eb_rearm_confirmed_number=number(Section.EB_REARM_CONFIRMATION),
            last_balise_header=self._last_balise_header,
        )
        self.status.post(status)
        return status
