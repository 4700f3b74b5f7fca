"""The operator of a whole-stack run: the scenario's actions, and answers to the Vital Control.

Between two slices of simulated time the operator does the scenario's actions in file order,
each once its time and its condition hold (``[[actions]]``: send a journey, engage, drive
remotely, confirm a VC request, issue an MA...), through the trackside's REST API as the
console does; the trackside's simulated operator answers the VC's vigilance and EB-rearm
requests while the operator is present; and with ``operator.reengage`` ATO is engaged again
after a fallback stop.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from deploy.scenario.conditions import State
from deploy.scenario.run_context import RunContext, ScenarioRunError, wait_for
from deploy.scenario.schema import Action
from deploy.scenario.trackside_harness import TracksideHarness
from protocol import messages as m

__all__ = ["CONFIRMATIONS", "OperatorScript", "ma_summary"]

CONFIRMATIONS = {
    "confirm_rearm": (m.OperatorRequestKind.EB_REARM, "confirmations/eb-rearm"),
    "isolate_etcs": (m.OperatorRequestKind.ETCS_ISOLATION, "confirmations/etcs-isolation"),
    "insert_etcs": (m.OperatorRequestKind.ETCS_INSERTION, "confirmations/etcs-insertion"),
    "vigilance_ack": (m.OperatorRequestKind.VIGILANCE, "confirmations/vigilance-ack"),
}
"""Actions that confirm a VC request: the request's kind and the confirmation's route."""


def ma_summary(answer: dict[str, Any]) -> str:
    """An issued MA as the run's log keeps it: its number, change and extent. Not the answer's
    text, which carries the session's id and number (new and random in every run): the log,
    and ``kpis.json`` with it, are the same for the same scenario and seed."""
    ma = answer["movement_authority"]
    authority = ma.get("authority") or {}
    extent = (
        f"{authority['start_m']:.1f} → {authority['end_of_authority_m']:.1f} m"
        if authority
        else "revoked"
    )
    return f"MA {ma['ma_id']} {ma['change']}: {extent}"


class OperatorScript:
    """Does the scenario's actions and answers the VC, between slices."""

    def __init__(self, ctx: RunContext, trackside: TracksideHarness) -> None:
        self.ctx = ctx
        self.trackside = trackside
        self.next_action = 0
        """The index of the next action to do."""
        self._armed_s = 0.0
        self._ready_since_s: float | None = None

    def act(self, state: State, refresh: Callable[[], State]) -> bool:
        """Do the actions due now (``refresh()`` gives the state after each); False when one
        timed out (the run stops)."""
        ctx = self.ctx
        actions = ctx.spec.actions
        while self.next_action < len(actions):
            action = actions[self.next_action]
            now_s = float(state["time_s"])
            if now_s - self._armed_s > action.timeout_s:
                ctx.failures.append(
                    f"action {self.next_action + 1} ({action.do}) timed out after "
                    f"{action.timeout_s:.0f} s"
                )
                return False
            if not self._due(action, state):
                return True
            self.do(action)
            self.next_action += 1
            self._armed_s = now_s
            state = refresh()
        return True

    def note_pending(self) -> None:
        """At the end of the run: an action never done is a failure."""
        actions = self.ctx.spec.actions
        if self.next_action < len(actions):
            pending = actions[self.next_action]
            self.ctx.failures.append(f"action {self.next_action + 1} ({pending.do}) never happened")

    def _due(self, action: Action, state: State) -> bool:
        now_s = float(state["time_s"])
        if action.at_s is not None and now_s < action.at_s:
            return False
        if action.after_s is not None and now_s < self._armed_s + action.after_s:
            return False
        condition = action.condition
        return condition is None or condition.holds(state)

    def do(self, action: Action) -> None:
        """One action, now, logged; a refusal or a failure is a failure of the run."""
        ctx, trackside = self.ctx, self.trackside
        now_s = ctx.now_s
        trackside.select()
        if action.do == "issue_ma":
            assert action.end_of_authority_m is not None
            answer = trackside.movement_authority(action.end_of_authority_m)
            accepted = answer.status_code in (200, 201)
            detail = ma_summary(answer.json()) if accepted else answer.text[:200]
            ctx.log(action.do, accepted, detail, at_s=now_s)
            if not accepted:
                ctx.failures.append(f"issue_ma at {now_s:.1f} s refused: {answer.text[:200]}")
            return
        if action.do == "see_event":
            assert action.event is not None
            seen = trackside.wait_for_event(action.event)
            ctx.log(action.do, seen is not None, seen or f"no {action.event} event", at_s=now_s)
            if seen is None:
                ctx.failures.append(
                    f"see_event at {now_s:.1f} s: no {action.event} event in the trackside's log"
                )
            return
        if action.do == "send_journey":
            accepted, detail = trackside.send_journey()
            ctx.log(action.do, accepted, detail, at_s=now_s)
            if not accepted:
                ctx.failures.append(f"journey refused: {detail}")
            return
        route, body = self._route(action)
        if route is None:
            ctx.log(action.do, False, "no such request pending", at_s=now_s)
            ctx.failures.append(f"{action.do} at {now_s:.1f} s: no such request pending")
            return
        answer = trackside.command(route, body)
        if answer.status_code != 200:
            detail = f"{answer.status_code}: {answer.text[:200]}"
            ctx.log(action.do, False, detail, at_s=now_s)
            ctx.failures.append(f"{action.do} at {now_s:.1f} s failed: {detail}")
            return
        reply = answer.json()
        ctx.log(action.do, reply["accepted"], reply["reason"], at_s=now_s)
        if not reply["accepted"]:
            ctx.failures.append(f"{action.do} at {now_s:.1f} s refused: {reply['reason']}")

    def reengage(self, state: State) -> None:
        """``operator.reengage``: engage again once ATO has stood ready for the reaction time,
        after the journey was first engaged."""
        ctx = self.ctx
        if not ctx.spec.operator.reengage:
            return
        engaged = any(log.action == "engage" and log.accepted for log in ctx.actions)
        now_s = float(state["time_s"])
        if not engaged or state["ato_state"] != m.AtoState.READY.value:
            self._ready_since_s = None
            return
        if self._ready_since_s is None:
            self._ready_since_s = now_s
        if now_s - self._ready_since_s >= ctx.spec.operator.reaction_s:
            self._ready_since_s = None
            self.do(Action(do="engage"))

    def answer_vc(self) -> None:
        """The trackside's simulated operator looks at the vehicle's state now and answers what
        is due; the run goes on once the vehicle has its answers (so they reach it at a tick
        fixed by simulated time)."""
        if not self.ctx.operator_present:
            return
        thread = self.trackside.simulated_operator
        if thread is None:
            return
        operator = thread.operator
        if operator.step(self.ctx.node.current_status()):
            vehicle = self.ctx.spec.vehicle.id
            if not wait_for(lambda: operator.outstanding(vehicle) == 0):
                raise ScenarioRunError("the simulated operator's answer never came back")

    def _pending(self, kind: m.OperatorRequestKind) -> m.OperatorRequest | None:
        """The unconfirmed VC request of ``kind`` the vehicle shows now, if any."""
        status = self.ctx.node.stack.vital_status()
        if status is None:
            return None
        for request in status.operator_requests:
            if request.kind is kind and not request.confirmed:
                return request
        return None

    def _route(self, action: Action) -> tuple[str | None, dict[str, Any]]:
        """The remote-driver route of an action and its body (None: no request to answer)."""
        if action.do in CONFIRMATIONS:
            kind, route = CONFIRMATIONS[action.do]
            pending = self._pending(kind)
            return (None, {}) if pending is None else (route, {"number": pending.number})
        if action.do == "rd_target_speed":
            return "rd-target-speed", {"target_speed_kmh": action.speed_kmh}
        return action.do.replace("_", "-"), {}
