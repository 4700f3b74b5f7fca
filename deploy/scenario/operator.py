"""The remote operator's hands in lockstep runs: answers the Vital Control's requests.

A node fitted with the VC stands braked until the operator confirms the EB rearm, and brakes
when a vigilance request goes unanswered. Between two slices of simulated time, this operator
reads the requests the node reports and answers each one through a real Zenoh command, as the
trackside's console (or its simulated operator) does, once its reaction time has passed since
it first saw the request; the command is executed at the node's next commands tick, so the run
stays deterministic. ``present = False`` is an operator who has left the console.

The operator commands as a trackside does, through a trackside's Zenoh bridge of its own
(:class:`trackside.bridge.ZenohBridge`, holding the node's own line): the bridge answers the
node's handshake and track-data query, acknowledges its reports and seals each command with
the session's id and number, without which the node refuses it (``onboard.freshness``). The
operator waits for the node's session when it starts. Beside a trackside service (end-to-end
tests), it commands through that service's bridge instead (``trackside=`` or
:meth:`LockstepOperator.attach`), the one the node shakes hands with.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import zenoh

from deploy.scenario.run_context import ScenarioRunError, wait_for
from onboard.node import OnboardNode
from protocol import messages as m
from trackside.bridge import ZenohBridge

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
        session_limit_s: float = 5.0,
        trackside: ZenohBridge | Literal["own"] | None = "own",
    ) -> None:
        self.session = session
        self.node = node
        self._owns_bridge = trackside == "own"
        self.bridge = _own_bridge(session, node, name) if trackside == "own" else trackside
        """The trackside's bridge the commands go through (None: none yet, or gone)."""
        self.present = present
        """False: the operator has left the console and answers nothing."""
        self.reaction_s = reaction_s
        self.name = name
        self.answers: list[m.CommandAck] = []
        self._seen_s: dict[tuple[m.OperatorRequestKind, int], float] = {}
        self._command_id = 10_000
        if self._owns_bridge:
            self._open_session(session_limit_s)

    def attach(self, bridge: ZenohBridge | None) -> None:
        """Command through a trackside service's bridge from now on (None: no trackside)."""
        self.bridge = bridge

    def _open_session(self, limit_s: float) -> None:
        """Run the node until it holds a session with the bridge (at most ``limit_s`` of
        simulated time), once it sees the bridge's trackside token."""
        node = self.node
        wait_for(lambda: node.trackside_seen)
        end_s = node.clock.now_s + limit_s
        while not node.session_client.established and node.clock.now_s < end_s:
            node.run(0.1)

    def close(self) -> None:
        """Its own bridge's subscriptions and token go (the node's session then lapses)."""
        if self._owns_bridge and self.bridge is not None:
            self.bridge.close()

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
        if status is None or not self.present or self.bridge is None:
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
        if self.bridge is None:
            raise ScenarioRunError("the operator has no trackside to command through")
        ack = self.bridge.command(command, timeout_s=REQUEST_TIMEOUT_S)
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


def _own_bridge(session: zenoh.Session, node: OnboardNode, name: str) -> ZenohBridge:
    """A trackside's bridge of the operator's own, holding the node's line."""
    line = node.track_map
    return ZenohBridge(
        session,
        instance_id=f"{name}-trackside",
        line_version=lambda line_id: line.version if line_id == line.line.id else None,
    )
