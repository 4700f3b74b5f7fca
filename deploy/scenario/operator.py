"""The remote operator's hands in lockstep runs: answers the Vital Control's requests.

A node fitted with the VC stands braked until the operator confirms the EB rearm, and brakes
when a vigilance request goes unanswered. Between two slices of simulated time, this operator
reads the requests the node reports and answers each one through a real Zenoh command, as the
trackside's console (or its simulated operator) does, once its reaction time has passed since
it first saw the request; the command is executed at the node's next commands tick, so the run
stays deterministic. ``present = False`` is an operator who has left the console.
"""

from __future__ import annotations

from collections.abc import Callable

import zenoh

from onboard.node import OnboardNode
from protocol import messages as m
from protocol import request
from protocol.registry import COMMAND

__all__ = ["ANSWERED", "REQUEST_TIMEOUT_S", "LockstepOperator"]

ANSWERED = (m.OperatorRequestKind.VIGILANCE, m.OperatorRequestKind.EB_REARM)
REQUEST_TIMEOUT_S = 10.0
"""Wall time a command may take to be answered. The vehicle answers on arrival and nothing in a
lockstep run moves meanwhile, so a slow answer only means a loaded machine."""
"""What a simulated operator confirms of its own accord; ETCS isolation and insertion are
confirmed only when a scenario's action asks for them."""


class LockstepOperator:
    """Confirms vigilance and EB-rearm requests of ``node`` through ``session``."""

    def __init__(
        self,
        session: zenoh.Session,
        node: OnboardNode,
        *,
        present: bool = True,
        reaction_s: float = 0.0,
        name: str = "simulated-operator",
    ) -> None:
        self.session = session
        self.node = node
        self.present = present
        """False: the operator has left the console and answers nothing."""
        self.reaction_s = reaction_s
        self.name = name
        self.answers: list[m.CommandAck] = []
        self._seen_s: dict[tuple[m.OperatorRequestKind, int], float] = {}
        self._command_id = 10_000

    def pending(self, kind: m.OperatorRequestKind) -> m.OperatorRequest | None:
        """The unconfirmed request of ``kind`` the node shows now, if any."""
        status = self.node.stack.vital_status()
        if status is None:
            return None
        for request_ in status.operator_requests:
            if request_.kind is kind and not request_.confirmed:
                return request_
        return None

    def answer(self) -> None:
        """Answer what the node shows now, once the reaction time has passed (call between
        slices)."""
        status = self.node.stack.vital_status()
        if status is None or not self.present:
            return
        now_s = self.node.clock.now_s
        for pending in status.operator_requests:
            if pending.kind not in ANSWERED or pending.confirmed:
                continue
            seen_s = self._seen_s.setdefault((pending.kind, pending.number), now_s)
            if now_s - seen_s >= self.reaction_s:
                self.command(m.OperatorConfirmCommand(request=pending.kind, number=pending.number))

    def command(self, body: m.CommandBody) -> m.CommandAck:
        self._command_id += 1
        command = m.Command(
            vehicle_id=self.node.vehicle_id,
            command_id=self._command_id,
            issued_by=self.name,
            body=body,
        )
        ack = request(
            self.session,
            COMMAND,
            command,
            timeout_s=REQUEST_TIMEOUT_S,
            vehicle=self.node.vehicle_id,
        )
        self.answers.append(ack)
        return ack

    def run(self, duration_s: float, *, slice_s: float = 0.2) -> None:
        """Run the node for ``duration_s`` of simulated time, answering between slices."""
        end_s = self.node.clock.now_s + duration_s
        while self.node.clock.now_s < end_s - 1e-9:
            self.answer()
            self.node.run(min(slice_s, end_s - self.node.clock.now_s))

    def run_until(
        self, condition: Callable[[], bool], limit_s: float, slice_s: float = 0.2
    ) -> bool:
        """Run until ``condition`` holds (checked between slices), at most ``limit_s``."""
        end_s = self.node.clock.now_s + limit_s
        while self.node.clock.now_s < end_s:
            if condition():
                return True
            self.answer()
            self.node.run(slice_s)
        return condition()
