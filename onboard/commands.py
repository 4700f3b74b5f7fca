"""Trackside commands on board: checked on arrival, executed at the next ``commands`` tick.

A command is acknowledged as soon as it arrives (on Zenoh's thread) with :meth:`CommandDesk.
refusal`'s verdict, and what it changes happens later, at a tick of simulated time, through
:meth:`CommandDesk.execute`, which may still refuse it (the train's state may have changed in
between). Each kind of command has one handler in a table keyed by its body's type.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from typing import Any

from pydantic import BaseModel

from onboard.events import StackEvent
from onboard.freshness import FreshnessGuard
from onboard.stack import OnboardStack
from onboard.vital_interface import NO_VITAL_CONTROL
from protocol import messages as m
from protocol.units import MPS_PER_KMH

__all__ = ["CommandDesk", "command_refusal"]

Verdict = tuple[str | None, StackEvent | None]
"""A handler's refusal (None: obeyed) and the event it is logged by when obeyed."""
_Handler = Callable[[Any, str, float], Verdict]

_INFO, _WARNING = m.EventSeverity.INFO, m.EventSeverity.WARNING


class CommandDesk:
    """Takes the trackside's commands for ``vehicle_id`` and executes them on an
    :class:`~onboard.stack.OnboardStack`; ``now_s`` gives the simulated time for the
    acknowledgements; ``guard`` takes only the commands of the session held, each once (none:
    every command is taken, for tests of the stack alone)."""

    def __init__(
        self,
        stack: OnboardStack,
        vehicle_id: str,
        now_s: Callable[[], float],
        guard: FreshnessGuard | None = None,
    ) -> None:
        self.stack = stack
        self.vehicle_id = vehicle_id
        self._now_s = now_s
        self._guard = guard
        self.rejected = 0
        """Commands refused on arrival."""
        self._refusals: list[StackEvent] = []
        """Commands refused as not fresh, logged at the next :meth:`execute_queued`."""
        self._queue: deque[m.Command] = deque()
        self._lock = threading.Lock()
        self._handlers: dict[type[BaseModel], _Handler] = {
            m.RemoteDrivingTargetCommand: self._remote_target,
            m.EngageCommand: self._engage,
            m.DisengageCommand: self._disengage,
            m.SkipStopCommand: self._skip_stop,
            m.TrainHoldCommand: self._train_hold,
            m.EmergencyBrakeCommand: self._emergency_brake,
            m.OperatorConfirmCommand: self._confirm,
        }

    def on_command(self, _chunks: dict[str, str], command: m.Command) -> m.CommandAck:
        """A command's acknowledgement on arrival (Zenoh's thread); one accepted is queued for
        :meth:`execute_queued` (a ping only answers)."""
        reason = self._stale(command) or self.refusal(command)
        if reason is None and not isinstance(command.body, m.PingCommand):
            with self._lock:
                self._queue.append(command)
        if reason is not None:
            self.rejected += 1
        return m.CommandAck(
            vehicle_id=self.vehicle_id,
            command_id=command.command_id,
            accepted=reason is None,
            reason=reason,
            sim_time_s=self._now_s(),
        )

    def _stale(self, command: m.Command) -> str | None:
        """Why the command is not of the session held or not new, if so (logged)."""
        if self._guard is None or command.vehicle_id != self.vehicle_id:
            return None
        refusal = self._guard.admit(command.freshness)
        if refusal is None:
            return None
        text = f"command {command.command_id} ({command.body.type}) refused: {refusal.value}"
        with self._lock:
            self._refusals.append(StackEvent(_WARNING, "session.refused", text))
        return refusal.value

    def refusal(self, command: m.Command) -> str | None:
        """Why the command cannot be obeyed now, if it cannot (checked on arrival)."""
        if command.vehicle_id != self.vehicle_id:
            return f"command for {command.vehicle_id} reached {self.vehicle_id}"
        return command_refusal(self.stack, command.body)

    def execute_queued(self, now_s: float) -> list[StackEvent]:
        """Execute the commands queued since the last call, in arrival order; their events."""
        with self._lock:
            events, self._refusals = self._refusals, []
        while True:
            with self._lock:
                if not self._queue:
                    return events
                command = self._queue.popleft()
            events.extend(self.execute(command, now_s))

    def execute(self, command: m.Command, now_s: float) -> list[StackEvent]:
        """Obey an accepted command now; the events it is logged by (a refusal among them)."""
        handler = self._handlers.get(type(command.body))
        if handler is None:
            return []
        refused, event = handler(command.body, command.issued_by, now_s)
        if refused is not None:
            text = f"command {command.command_id}: {refused}"
            return [StackEvent(_WARNING, "command.refused", text)]
        return [] if event is None else [event]

    # -- one handler per command -----------------------------------------------------------------

    def _remote_target(self, body: m.RemoteDrivingTargetCommand, by: str, now_s: float) -> Verdict:
        if (refused := command_refusal(self.stack, body)) is not None:
            return refused, None
        self.stack.remote(body.target_speed_mps, now_s)
        text = f"target {body.target_speed_mps / MPS_PER_KMH:.1f} km/h by {by}"
        return None, StackEvent(_INFO, "rd.target_speed", text)

    def _engage(self, _body: m.EngageCommand, by: str, now_s: float) -> Verdict:
        refused = self.stack.engage(now_s)
        return refused, StackEvent(_INFO, "ato.engaged", f"by {by}")

    def _disengage(self, _body: m.DisengageCommand, by: str, now_s: float) -> Verdict:
        refused = self.stack.disengage(now_s)
        return refused, StackEvent(_INFO, "ato.disengaged", f"by {by}")

    def _skip_stop(self, body: m.SkipStopCommand, by: str, now_s: float) -> Verdict:
        if (refused := command_refusal(self.stack, body)) is not None:
            return refused, None
        self.stack.skip_stop(body.timing_point_id, now_s)
        text = f"{body.timing_point_id} skipped by {by}"
        return None, StackEvent(_INFO, "journey.skip_stop", text)

    def _train_hold(self, body: m.TrainHoldCommand, by: str, now_s: float) -> Verdict:
        if (refused := command_refusal(self.stack, body)) is not None:
            return refused, None
        self.stack.train_hold(body.hold, now_s)
        text = f"{'held' if body.hold else 'released'} by {by}"
        return None, StackEvent(_INFO, "journey.train_hold", text)

    def _emergency_brake(self, _body: m.EmergencyBrakeCommand, by: str, _now_s: float) -> Verdict:
        refused = self.stack.vital_interface.operator_emergency_brake()
        return refused, StackEvent(_WARNING, "operator.emergency_brake", f"by {by}")

    def _confirm(self, body: m.OperatorConfirmCommand, by: str, _now_s: float) -> Verdict:
        refused = self.stack.vital_interface.operator_confirm(body.request, body.number)
        code = f"operator.confirm.{body.request.value}"
        return refused, StackEvent(_INFO, code, f"request {body.number} by {by}")


def command_refusal(stack: OnboardStack, body: m.CommandBody) -> str | None:
    """Why a command cannot be obeyed now by ``stack``, if it cannot."""
    state = stack.controller.state
    if isinstance(body, m.EngageCommand):
        if stack.journey_plan is None:
            return "ATO-OB not available: no journey profile accepted"
        if state is not m.AtoState.READY:
            output = stack.controller.output
            reasons = output.unavailable_reasons + output.not_ready_reasons
            failed = ", ".join(str(r) for r in reasons) or "conditions pending"
            return f"ATO-OB is {state.value}, not ready ({failed})"
    if isinstance(body, m.DisengageCommand) and not stack.engaged:
        return "ATO-OB is not engaged"
    if isinstance(body, m.RemoteDrivingTargetCommand):
        if stack.engaged:
            return "ATO engaged: disengage before remote driving"
        limit = stack.track_map.speed_limit_mps(stack.position_m)
        if body.target_speed_mps > limit:
            return f"target {body.target_speed_mps:.2f} m/s above line speed {limit:.2f} m/s"
    if isinstance(body, m.EmergencyBrakeCommand) and not stack.vital_links:
        return NO_VITAL_CONTROL
    if isinstance(body, m.OperatorConfirmCommand):
        return stack.vital_interface.confirm_refusal(body.request, body.number)
    if isinstance(body, m.SkipStopCommand):
        return _skip_refusal(stack, body.timing_point_id)
    if isinstance(body, m.TrainHoldCommand) and stack.journey_plan is None:
        return "no journey profile accepted"
    return None


def _skip_refusal(stack: OnboardStack, timing_point_id: str) -> str | None:
    ahead = stack.journey.stops_ahead(stack.position_m)
    if ahead is None:
        return "no journey profile accepted"
    for stop in ahead:
        if stop.timing_point_id == timing_point_id:
            if stop.end_of_journey:
                return f"{timing_point_id} ends the journey: it cannot be skipped"
            return None
    return f"{timing_point_id} is not a stopping point ahead on the journey"
