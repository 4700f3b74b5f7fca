"""Task C, the actuator (seed 004 §2.4, Table 4; DOMAIN.md §7.2): every 2 ms, right after B.

Two parallel regions (see :mod:`onboard.vc.fsm`):

- the **brake**: on Task B's EB flag it de-energises the solenoid valves (the pipe vents, full EB
  450 ms later); it waits for standstill; it rearms (energises the valves) only at standstill,
  with no hazard and the flag down, on the operator's EB Rearm Confirmation, and verifies the
  rearm on the EB input within ``rearm_timeout_s``, else System Decay (scenario G). In System
  Decay the valves stay de-energised until a restart.
- the **ETCS relay**: on the operator's ETCS Isolation (Insertion) Confirmation, at standstill,
  it commands the radio relay and verifies the contact on the ETCS input, as re-read by Task B,
  within ``relay_verification_timeout_s``, else System Decay (scenario F).

A confirmation is identified by its request's sequence number and acted on once. One that comes
when it cannot be acted on (moving, System Decay) is refused and logged.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from onboard.vc.config import TIME_TOLERANCE_S, VcConfig
from onboard.vc.fsm import (
    TASK_C_BRAKE_TRANSITIONS,
    TASK_C_ETCS_TRANSITIONS,
    BrakeState,
    EtcsState,
    StateMachine,
    Trigger,
)
from onboard.vc.ipc import ActuationStatus, Mailbox, SupervisionStatus, VcEvent, VcEventKind
from onboard.vc.messages import DecayReason
from onboard.vc.quiet import QuietCycles

__all__ = ["TaskC"]

_VALVES_ENERGISED = frozenset({BrakeState.RELEASED, BrakeState.REARMING})
_RELAY_INSERTED = frozenset({EtcsState.INSERTED, EtcsState.INSERTING})


class TaskC:
    """Task C of one VC.

    Parameters
    ----------
    supervision
        Task B's latest status.
    command_valves, command_relay
        The outputs: ``(energised, now_s)`` for the EB valves, ``(inserted, now_s)`` for the
        ETCS radio relay.
    etcs_inserted
        The relay at power-up.
    status
        Where Task C posts its own (a new mailbox by default).
    """

    def __init__(
        self,
        config: VcConfig,
        *,
        supervision: Mailbox[SupervisionStatus],
        command_valves: Callable[[bool, float], None],
        command_relay: Callable[[bool, float], None],
        etcs_inserted: bool = True,
        status: Mailbox[ActuationStatus] | None = None,
    ) -> None:
        self.config = config
        self.status = status if status is not None else Mailbox[ActuationStatus]()
        self.brake = StateMachine(TASK_C_BRAKE_TRANSITIONS, BrakeState.BRAKING)
        self.etcs = StateMachine(
            TASK_C_ETCS_TRANSITIONS, EtcsState.INSERTED if etcs_inserted else EtcsState.ISOLATED
        )
        self.events: list[VcEvent] = []
        self._supervision = supervision
        self._command_valves = command_valves
        self._command_relay = command_relay
        self._decay_reasons: list[DecayReason] = []
        self._decay_reasons_published: tuple[DecayReason, ...] = ()
        self._switch_started_s = 0.0
        self._rearm_started_s = 0.0
        self._consumed: dict[str, int | None] = {
            "isolation": None,
            "insertion": None,
            "rearm": None,
        }
        self._refused: set[tuple[str, int]] = set()
        self.quiet = QuietCycles()
        """Skips the cycles that cannot change anything (lockstep only: :mod:`onboard.vc.quiet`)."""
        self._input: SupervisionStatus | None = None
        self._actuation: ActuationStatus | None = None

    def _event(
        self, now_s: float, kind: VcEventKind, detail: str, evidence_s: float | None = None
    ) -> None:
        self.events.append(
            VcEvent(time_s=now_s, task="C", kind=kind, detail=detail, evidence_s=evidence_s)
        )

    def _new(self, name: str, number: int | None) -> bool:
        return number is not None and number != self._consumed[name]

    def _refuse(self, now_s: float, name: str, number: int | None, why: str) -> None:
        if number is not None and (name, number) not in self._refused:
            self._refused.add((name, number))
            self._event(now_s, VcEventKind.REQUEST_REFUSED, f"{name} #{number}: {why}")

    def _decay(self, now_s: float, reason: DecayReason, evidence_s: float) -> None:
        if not self._decay_reasons:
            self._event(now_s, VcEventKind.SYSTEM_DECAY, reason.value, evidence_s)
        self._decay_reasons.append(reason)

    # -- ETCS region -----------------------------------------------------------------------

    def _etcs_triggers(
        self, now_s: float, status: SupervisionStatus, decayed: bool
    ) -> set[Trigger]:
        state = self.etcs.state
        triggers: set[Trigger] = set()
        timeout_s = self.config.relay_verification_timeout_s
        overdue = now_s > self._switch_started_s + timeout_s + TIME_TOLERANCE_S
        if state is EtcsState.INSERTED:
            number = status.etcs_isolation_confirmed_number
            if self._new("isolation", number):
                if status.standstill and not decayed:
                    triggers.add(Trigger.ISOLATION_CONFIRMED)
                else:
                    self._refuse(now_s, "isolation", number, "not at standstill or in decay")
        elif state is EtcsState.ISOLATED:
            number = status.etcs_insertion_confirmed_number
            if self._new("insertion", number):
                if status.standstill and not decayed:
                    triggers.add(Trigger.INSERTION_CONFIRMED)
                else:
                    self._refuse(now_s, "insertion", number, "not at standstill or in decay")
        elif state is EtcsState.ISOLATING:
            if status.etcs_isolated:
                triggers.add(Trigger.ISOLATION_VERIFIED)
            elif overdue:
                triggers.add(Trigger.ISOLATION_NOT_ACTUATED)
        elif state is EtcsState.INSERTING:
            if not status.etcs_isolated:
                triggers.add(Trigger.INSERTION_VERIFIED)
            elif overdue:
                triggers.add(Trigger.INSERTION_NOT_ACTUATED)
        return triggers

    def _step_etcs(self, now_s: float, status: SupervisionStatus, decayed: bool) -> None:
        rule = self.etcs.fire(self._etcs_triggers(now_s, status, decayed), now_s)
        if rule is None:
            return
        target = rule.target
        if target is EtcsState.ISOLATING:
            self._consumed["isolation"] = status.etcs_isolation_confirmed_number
            self._switch_started_s = now_s
        elif target is EtcsState.INSERTING:
            self._consumed["insertion"] = status.etcs_insertion_confirmed_number
            self._switch_started_s = now_s
        elif target is EtcsState.ISOLATED:
            self._event(now_s, VcEventKind.ETCS_ISOLATED, "relay re-read: isolated")
        elif target is EtcsState.INSERTED:
            self._event(now_s, VcEventKind.ETCS_INSERTED, "relay re-read: inserted")
        else:
            reason = (
                DecayReason.ETCS_ISOLATION_NOT_ACTUATED
                if rule.trigger is Trigger.ISOLATION_NOT_ACTUATED
                else DecayReason.ETCS_INSERTION_NOT_ACTUATED
            )
            deadline_s = self._switch_started_s + self.config.relay_verification_timeout_s
            self._decay(now_s, reason, deadline_s)
        self._command_relay(self.etcs.state in _RELAY_INSERTED, now_s)

    # -- brake region ----------------------------------------------------------------------

    def _brake_triggers(
        self, now_s: float, status: SupervisionStatus, decayed: bool
    ) -> set[Trigger]:
        state = self.brake.state
        triggers: set[Trigger] = set()
        if decayed:
            triggers.add(Trigger.SYSTEM_DECAY)
        if status.eb_flag:
            triggers.add(Trigger.EB_FLAG)
        if state is BrakeState.BRAKING and status.standstill:
            triggers.add(Trigger.STANDSTILL)
        if state is BrakeState.REARMING:
            if status.eb_released:
                triggers.add(Trigger.REARM_VERIFIED)
            elif now_s > self._rearm_started_s + self.config.rearm_timeout_s + TIME_TOLERANCE_S:
                triggers.add(Trigger.REARM_NOT_APPLIED)
        number = status.eb_rearm_confirmed_number
        if self._new("rearm", number):
            safe = not (status.eb_flag or status.live_conditions or decayed)
            if state is BrakeState.STANDSTILL and status.standstill and safe:
                triggers.add(Trigger.REARM_CONFIRMED)
            elif state is not BrakeState.REARMING:
                self._refuse(now_s, "rearm", number, "not at standstill, or not safe")
        return triggers

    def _step_brake(self, now_s: float, status: SupervisionStatus, decayed: bool) -> None:
        energised_before = self.brake.state in _VALVES_ENERGISED
        rule = self.brake.fire(self._brake_triggers(now_s, status, decayed), now_s)
        if rule is not None:
            if rule.target is BrakeState.REARMING:
                self._consumed["rearm"] = status.eb_rearm_confirmed_number
                self._rearm_started_s = now_s
            elif rule.target is BrakeState.RELEASED:
                self._event(now_s, VcEventKind.EB_REARMED, "EB input: released")
            elif rule.trigger is Trigger.REARM_NOT_APPLIED:
                deadline_s = self._rearm_started_s + self.config.rearm_timeout_s
                self._decay(now_s, DecayReason.EB_REARM_NOT_APPLIED, deadline_s)
        energised = self.brake.state in _VALVES_ENERGISED
        if energised_before and not energised:
            self._event(
                now_s, VcEventKind.EB_COMMANDED, f"valves de-energised ({self.brake.state})"
            )
        self._command_valves(energised, now_s)

    # -- the cycle -------------------------------------------------------------------------

    def step(self, now_s: float) -> ActuationStatus:
        """One cycle at ``now_s``; returns (and posts) the status."""
        status = self._supervision.read()
        quiet, last = self.quiet, self._actuation
        if (
            quiet.enabled
            and now_s <= quiet.until_s
            and last is not None
            and status is not None
            and self._input is not None
            and status[1:] == self._input[1:]
        ):
            # Task B's status but for its time, no threshold crossed: a repeated fixed point.
            quiet.skipped += 1
            actuation = ActuationStatus._make((now_s, *last[1:]))
            self.status.post(actuation)
            return actuation
        actuation = self._full_cycle(now_s, status)
        if quiet.enabled:
            self._input, self._actuation = status, actuation
            quiet.after_full_cycle(
                now_s,
                self._fingerprint(actuation),
                took_input=False,
                thresholds=self._thresholds_s,
            )
        return actuation

    def _thresholds_s(self) -> tuple[float, float]:
        """The instants past which a cycle with the same input would differ (the relay's
        verification, the rearm timed out)."""
        return (
            self._switch_started_s + self.config.relay_verification_timeout_s + TIME_TOLERANCE_S,
            self._rearm_started_s + self.config.rearm_timeout_s + TIME_TOLERANCE_S,
        )

    def quiet_horizon_s(self) -> float:
        """Until when [s] the cycles stay quiet while Task B's status does (−inf: the next
        one may not be)."""
        if self._actuation is None or self._input is None:
            return -math.inf
        return self.quiet.until_s  # −inf unless enabled and the last full cycle was fixed

    def _fingerprint(self, actuation: ActuationStatus) -> tuple[object, ...]:
        """Every piece of state a cycle can change, and its status but for the time."""
        return (
            actuation[1:],
            self.brake.state,
            len(self.brake.transitions),
            self.etcs.state,
            len(self.etcs.transitions),
            len(self.events),
            len(self._decay_reasons),
            self._switch_started_s,
            self._rearm_started_s,
            tuple(self._consumed.values()),
            len(self._refused),
        )

    def _full_cycle(self, now_s: float, status: SupervisionStatus | None) -> ActuationStatus:
        if status is not None:
            self._step_etcs(now_s, status, status.system_decay or bool(self._decay_reasons))
            self._step_brake(now_s, status, status.system_decay or bool(self._decay_reasons))
        else:
            self._command_valves(self.brake.state in _VALVES_ENERGISED, now_s)
        reasons = self._decay_reasons
        if len(reasons) != len(self._decay_reasons_published):
            # Reasons are only ever appended: the tuple is rebuilt when one is, not every 2 ms.
            self._decay_reasons_published = tuple(reasons)
        brake_state = self.brake.state
        actuation = ActuationStatus(
            time_s=now_s,
            brake_state=brake_state,
            etcs_state=self.etcs.state,
            valves_energised=brake_state in _VALVES_ENERGISED,
            relay_inserted_commanded=self.etcs.state in _RELAY_INSERTED,
            system_decay=bool(reasons) or brake_state is BrakeState.DECAYED,
            decay_reasons=self._decay_reasons_published,
            consumed_rearm_number=self._consumed["rearm"],
        )
        self.status.post(actuation)
        return actuation
