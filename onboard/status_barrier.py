"""The lockstep barrier on the status link (ARCHITECTURE.md, "Time").

In lockstep the acknowledgement of each status report sent in an open session is taken at the
next status tick, one status period later, waiting for it there (up to :data:`BARRIER_S` of
wall time) if it has not come: the per-link barrier, pipelined so that the round trip overlaps
the simulation. A run in which no barrier ends without its acknowledgement does not depend on
the machine's speed. In real time nothing waits.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

__all__ = ["BARRIER_S", "RETRANSMIT_S", "StatusBarrier"]

BARRIER_S = 10.0
"""Lockstep: the longest wall time a status report waits for its acknowledgement. Long, so that a
loaded machine never changes a run; the wait ends at once when the trackside's liveliness token
goes, and is not made again until a session is established anew."""
RETRANSMIT_S = 2.0
"""Lockstep: after this long without an acknowledgement [s of wall time] the report is sent
once more (a report lost on the way would otherwise cost the session)."""


class StatusBarrier:
    """The wait for the last status report's acknowledgement (lockstep only).

    Attributes
    ----------
    acked : threading.Event
        Set by Zenoh's thread once an acknowledgement is queued (or the trackside went).
    misses : int
        Barriers that ended without the acknowledgement.
    retransmissions : int
        Reports sent once more for want of an acknowledgement.
    """

    def __init__(self, *, lockstep: bool) -> None:
        self.lockstep = lockstep
        self.acked = threading.Event()
        self.armed = True
        """Disarmed when the trackside's token goes; armed again by a new session."""
        self.pending = False
        """A report sent in a session waits for its acknowledgement at the next status tick."""
        self.misses = 0
        self.retransmissions = 0

    def on_ack(self) -> None:
        """An acknowledgement is queued (Zenoh's thread)."""
        self.acked.set()

    def disarm(self) -> None:
        """A trackside went away: no acknowledgement will come, so the barrier ends now and is
        not waited on again before the next handshake (Zenoh's thread)."""
        self.armed = False
        self.acked.set()

    def arm(self) -> None:
        """A session is established: its reports are waited for again."""
        self.armed = True

    def sending(self) -> None:
        """A report is about to go out: its acknowledgement is yet to come."""
        self.acked.clear()

    def sent(self, *, in_session: bool) -> None:
        """A report went out; in lockstep and in a session, it is waited for at the next tick."""
        self.pending = self.lockstep and in_session

    def take(self, resend: Callable[[], bool]) -> bool | None:
        """At a status tick: wait for the previous report's acknowledgement if one is pending.

        ``resend`` sends the last report once more (same ``seq``: the trackside counts a
        duplicate as stale) and says whether there was one to send. Returns None when nothing
        was waited for, else whether the acknowledgement came; a wait that ended without it
        is counted in :attr:`misses`."""
        if not self.pending:
            return None
        self.pending = False
        # Disarmed (the trackside's token went), no barrier is waited on: none is missed.
        if not self.armed:
            return None
        came = self._wait(resend)
        if not self.acked.is_set():
            self.misses += 1
        return came

    def _wait(self, resend: Callable[[], bool]) -> bool:
        if self.acked.wait(RETRANSMIT_S):
            return True
        if not self.armed or not resend():
            return False
        self.retransmissions += 1
        return self.acked.wait(BARRIER_S - RETRANSMIT_S)

    @property
    def outstanding(self) -> bool:
        """The last report sent in the session still waits for its acknowledgement."""
        return self.pending and not self.acked.is_set()
