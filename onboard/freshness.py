"""Fresh trackside messages on board: only from the session held, each number once.

The trackside stamps every command, journey profile, MA and TSR it sends with the id of the
session it holds with the vehicle (given in its HSAck) and a number, +1 per message in that
session (:class:`protocol.messages.Freshness`). :class:`FreshnessGuard` takes a message only
when a session is open, the id is that session's, and the number was not taken before and is
within :data:`WINDOW` of the highest taken: EN 50159's defences against repetition (a number
seen), insertion and masquerade (no or another session) and out-of-date messages (below the
window). Messages travel on several channels (commands are queries, the others publications),
so numbers may arrive a little out of order; the window takes that, and what has an order of
its own is kept in it elsewhere (an MA's ``ma_id``, a journey profile's version).

Each refusal is counted by its reason. The guard is shared between Zenoh's threads (commands
are checked on arrival) and the node's (the rest at the ``commands`` tick): one short lock.
"""

from __future__ import annotations

import threading
from collections import Counter
from enum import StrEnum

from protocol import messages as m

__all__ = ["WINDOW", "FreshnessGuard", "Refusal"]

WINDOW = 64
"""How far below the highest number taken a number may still arrive (and be taken once)."""


class Refusal(StrEnum):
    """Why a trackside message was not taken."""

    NO_SESSION = "no session with the trackside"
    UNSEALED = "no session id and number"
    OTHER_SESSION = "from another session"
    REPLAYED = "replayed: its number was already taken"
    STALE = "stale: its number is below the window"


class FreshnessGuard:
    """The open session's id and the numbers taken in it."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._session_id: str | None = None
        self._highest = 0
        self._taken: set[int] = set()
        self.refused: Counter[Refusal] = Counter()
        """Messages refused, by reason."""

    @property
    def session_id(self) -> str | None:
        with self._lock:
            return self._session_id

    def open(self, session_id: str) -> None:
        """A session was established: its messages are taken from now on, numbered afresh."""
        with self._lock:
            self._session_id = session_id
            self._highest = 0
            self._taken.clear()

    def close(self) -> None:
        """The session ended: nothing is taken until the next one."""
        with self._lock:
            self._session_id = None
            self._taken.clear()

    def admit(self, freshness: m.Freshness | None) -> Refusal | None:
        """Take the message's number (None), or say why it is refused (counted)."""
        with self._lock:
            refusal = self._check(freshness)
            if refusal is None:
                assert freshness is not None
                self._take(freshness.number)
            else:
                self.refused[refusal] += 1
            return refusal

    def _check(self, freshness: m.Freshness | None) -> Refusal | None:
        if self._session_id is None:
            return Refusal.NO_SESSION
        if freshness is None:
            return Refusal.UNSEALED
        if freshness.session_id != self._session_id:
            return Refusal.OTHER_SESSION
        if freshness.number in self._taken:
            return Refusal.REPLAYED
        if freshness.number <= self._highest - WINDOW:
            return Refusal.STALE
        return None

    def _take(self, number: int) -> None:
        self._taken.add(number)
        if number > self._highest:
            self._highest = number
            floor = number - WINDOW
            self._taken = {taken for taken in self._taken if taken > floor}
