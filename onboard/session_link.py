"""The session with the trackside, moved over the node's Zenoh ports (SUBSET-126's spirit).

:class:`~onboard.session.SessionClient` is the session's pure state machine;
:class:`SessionLink` carries its messages: the handshake (asked and waited for in lockstep,
answered on Zenoh's thread in real time), the status acknowledgements and the terminations
queued by the ports, and the events that say what became of the session.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

from onboard.ports import SessionReply, TracksidePorts
from onboard.runtime.clock import NS_PER_S
from onboard.session import SessionClient
from onboard.status_barrier import BARRIER_S, StatusBarrier
from protocol import ProtocolError, RequestTimeoutError
from protocol import messages as m

__all__ = ["HANDSHAKE_RETRY_S", "Emit", "SessionLink"]

HANDSHAKE_RETRY_S = 0.02
"""Lockstep: wall time between two tries of a handshake a seen trackside has not answered [s]."""

Emit = Callable[[m.EventSeverity, str, str, int], None]
"""Publishes an event: severity, code, text, at the instant [ns]."""

CurrentAuthority = Callable[[m.MovementAuthorityReply], None]
"""Takes the RBC's answer to "which MA and TSRs are in force for me"."""

CURRENT_AUTHORITY_TIMEOUT_S = 2.0
"""Lockstep: how long, in wall time, a new session waits for the RBC's MA and TSRs [s]."""


class SessionLink:
    """Steps a :class:`SessionClient` on what the ports received, and asks the handshake.

    Parameters
    ----------
    client : SessionClient
        The session's state machine.
    ports : TracksidePorts
        The vehicle's Zenoh seams.
    barrier : StatusBarrier
        The lockstep barrier, armed again by each new session.
    lockstep : bool
        Ask the handshake and wait for its answer at the tick (else asynchronously).
    emit : Emit
        Publishes the session's events.
    on_current_authority : CurrentAuthority, optional
        Takes the RBC's MA and TSRs in force, asked for at each new session (the vehicle may
        have started, or the trackside restarted, since it last heard them).
    """

    def __init__(
        self,
        client: SessionClient,
        ports: TracksidePorts,
        barrier: StatusBarrier,
        *,
        lockstep: bool,
        emit: Emit,
        on_current_authority: CurrentAuthority | None = None,
    ) -> None:
        self.client = client
        self.ports = ports
        self.barrier = barrier
        self.lockstep = lockstep
        self._emit = emit
        self._on_current_authority = on_current_authority
        self._trackside_seen = False
        self._replies: deque[SessionReply | None] = deque()
        self._lock = threading.Lock()

    def on_reply(self, reply: SessionReply) -> None:
        """A handshake's answer, on Zenoh's thread (real time): taken at the next step."""
        with self._lock:
            self._replies.append(reply)

    def step(self, now_ns: int, *, track_data_version: str | None) -> None:
        """Take acknowledgements, terminations and answers; check the timeouts; handshake when
        due (with the onboard's track-data version)."""
        now_s = now_ns / NS_PER_S
        client = self.client
        seen = self.ports.trackside_seen
        if seen and not self._trackside_seen:
            client.trackside_appeared(now_s)
        self._trackside_seen = seen
        for ack in self.ports.received_status_acks():
            client.on_status_ack(ack.vehicle_id, ack.seq, now_s)
        for termination in self.ports.received_terminations():
            if client.on_termination(termination, now_s):
                self._emit(
                    m.EventSeverity.WARNING, "session.terminated", termination.reason, now_ns
                )
        with self._lock:
            replies = list(self._replies)
            self._replies.clear()
        for reply in replies:
            self._take_reply(reply, now_ns)
        if client.step(now_s):
            text = f"no acknowledgement within {client.response_timeout_s} s"
            self._emit(m.EventSeverity.WARNING, "session.lost", text, now_ns)
        handshake = client.request(now_s, track_data_version=track_data_version)
        if handshake is None:
            return
        if self.lockstep:
            self._take_reply(self._lockstep_handshake(handshake), now_ns)
            return
        try:
            self.ports.ask_session_async(handshake, self.on_reply)
        except ProtocolError:
            self._take_reply(None, now_ns)

    def _lockstep_handshake(self, handshake: m.SessionRequest) -> SessionReply | None:
        """Lockstep: the handshake's answer, taken at the tick it was asked at. While a trackside's
        token is seen, the request is repeated (up to :data:`BARRIER_S` of wall time) until it is
        answered: the trackside's queryable may reach this session a moment after its token, and a
        loaded machine may answer late, neither of which may change the run. With no trackside
        seen, one try."""
        deadline = time.monotonic() + BARRIER_S
        while True:
            try:
                return self.ports.ask_session(handshake, timeout_s=1.0)
            except RequestTimeoutError:
                if not self.ports.trackside_seen or time.monotonic() > deadline:
                    return None
                time.sleep(HANDSHAKE_RETRY_S)
            except ProtocolError:
                return None

    def _take_reply(self, reply: SessionReply | None, now_ns: int) -> None:
        client = self.client
        client.on_response(reply, now_ns / NS_PER_S)
        if client.established:
            self.barrier.arm()
            text = f"with {client.trackside_id}"
            self._emit(m.EventSeverity.INFO, "session.established", text, now_ns)
            self._ask_current_authority(now_ns)
        elif isinstance(reply, m.SessionReject):
            self._emit(m.EventSeverity.WARNING, "session.rejected", reply.reason.value, now_ns)

    def _ask_current_authority(self, now_ns: int) -> None:
        """Ask the RBC for the MA and TSRs in force: waited for in lockstep (so they are taken
        at the next ``commands`` tick of every run), answered on Zenoh's thread in real time."""
        take = self._on_current_authority
        if take is None:
            return
        try:
            if not self.lockstep:
                self.ports.ask_current_authority_async(take)
                return
            take(self.ports.ask_current_authority(timeout_s=CURRENT_AUTHORITY_TIMEOUT_S))
        except ProtocolError as exc:
            self._emit(m.EventSeverity.INFO, "etcs.current_ma_unknown", str(exc), now_ns)
