"""The listener's reorder buffer: INPUT_PROTOCOL packets released in SEQ_NO order (seed 002 §3.2.1).

SEQ_NO is a uint16 that wraps, so order is modular: a packet is *ahead* of the next expected
number when its distance ``(seq − next) mod 65536`` is under half the range, *behind* otherwise.
A packet behind is dropped: a ``duplicate`` if it was released recently (or is already waiting),
``late`` otherwise. A packet ahead waits until the gap before it fills, or until the buffer holds
more than ``depth`` packets, or until ``max_wait_s`` have passed since the oldest waiting packet
arrived and since the last packet released had: the gap is then declared lost (counted) and
release resumes at the next number held. The second clause keeps a packet that arrived ahead
of packets still coming in order (a SEQ_NO corrupted a few numbers ahead) from having the gap
before it given up while that gap is filling, the packets of the gap then all ``late``. When its
turn comes, a packet that arrived more than ``max_wait_s`` before a packet released ahead of it
is **misplaced** (counted, not released, its number left open for the genuine packet): the
buffer tolerates no more reordering than that, so its SEQ_NO is not its own. A SEQ_NO corrupted
fewer numbers ahead than arrive in ``max_wait_s`` (6 at 122 packets a second) is released in
its place, the genuine packet of that number then being a ``duplicate``.

A packet more than ``window`` (2 × depth) ahead is ``out_of_window`` unless the packet that
arrived before it was out of the window too and at most ``depth`` behind it (a duplicate does
not count): one datagram alone never moves the order (a corrupted SEQ_NO would make every packet
after it late and push the epochs ahead), a sender that has moved on (a dead bus, a burst of
losses) is followed from its second packet.
"""

from __future__ import annotations

from collections import deque
from typing import Generic, TypeVar

from protocol.udp import SEQ_MODULO

__all__ = ["ReorderBuffer"]

T = TypeVar("T")
_HALF = SEQ_MODULO // 2


class ReorderBuffer(Generic[T]):
    """Holds items keyed by SEQ_NO and gives them back in order.

    Parameters
    ----------
    depth : int
        Packets held before a gap is given up.
    max_wait_s : float
        Longest a packet waits for the gap before it [s of arrival time].
    """

    def __init__(self, *, depth: int = 16, max_wait_s: float = 0.05) -> None:
        if depth < 1 or max_wait_s < 0:
            raise ValueError("depth must be ≥ 1 and max_wait_s ≥ 0")
        self.depth = depth
        self.max_wait_s = max_wait_s
        self.window = 2 * depth
        """Farthest a packet may be ahead of the next expected number on its own."""
        self.next_seq: int | None = None
        self.lost = 0
        """Sequence numbers declared lost when a gap was given up."""
        self.misplaced = 0
        """Packets refused on their turn: they arrived more than ``max_wait_s`` before a packet
        released ahead of them."""
        self._waiting: dict[int, tuple[T, float]] = {}
        self._recent: deque[int] = deque(maxlen=256)
        self._recent_set: set[int] = set()
        self._far_seq: int | None = None
        """SEQ_NO of the last packet that arrived out of the window, while no packet since has
        arrived in it."""
        self._released_arrival_s = -float("inf")
        """Latest arrival time of a packet released: a gap is waited for from there too."""

    def __len__(self) -> int:
        return len(self._waiting)

    def reset(self, next_seq: int | None = None) -> list[T]:
        """Forget the order (a sender restart); returns what was waiting, in order."""
        flushed = self.flush()
        self.next_seq = next_seq
        self._recent.clear()
        self._recent_set.clear()
        self._far_seq = None
        self._released_arrival_s = -float("inf")
        return flushed

    def distance(self, seq_no: int) -> int:
        """Modular distance of ``seq_no`` ahead of the next expected number (negative: behind)."""
        if self.next_seq is None:
            return 0
        delta = (seq_no - self.next_seq) % SEQ_MODULO
        return delta if delta < _HALF else delta - SEQ_MODULO

    def push(self, seq_no: int, item: T, arrival_s: float) -> str | None:
        """Offer an item; returns ``"duplicate"``, ``"late"`` or ``"out_of_window"`` when it is
        dropped, else None."""
        if self.next_seq is None:
            self.next_seq = seq_no
        delta = (seq_no - self.next_seq) % SEQ_MODULO
        if delta >= _HALF:
            return "duplicate" if seq_no in self._recent_set else "late"
        if delta > self.window:
            far, self._far_seq = self._far_seq, seq_no
            if far is None or not 0 < (seq_no - far) % SEQ_MODULO <= self.depth:
                return "out_of_window"
        else:
            self._far_seq = None
        if seq_no in self._waiting:
            return "duplicate"
        self._waiting[seq_no] = (item, arrival_s)
        return None

    def _mark_released(self, seq_no: int) -> None:
        if len(self._recent) == self._recent.maxlen:
            self._recent_set.discard(self._recent[0])
        self._recent.append(seq_no)
        self._recent_set.add(seq_no)

    def pop_ready(self, now_s: float) -> list[T]:
        """Release every item now due, in order, giving up gaps as the rules say."""
        released: list[T] = []
        waiting = self._waiting
        while waiting and self.next_seq is not None:
            seq_no = self.next_seq
            entry = waiting.pop(seq_no, None)
            if entry is None:
                oldest_s = min(arrival for _, arrival in waiting.values())
                since_s = max(oldest_s, self._released_arrival_s)
                if len(waiting) <= self.depth and now_s - since_s < self.max_wait_s:
                    break
                skip = min((key - seq_no) % SEQ_MODULO for key in waiting)
                self.lost += skip
                self.next_seq = (seq_no + skip) % SEQ_MODULO
                continue
            item, arrival_s = entry
            if arrival_s < self._released_arrival_s - self.max_wait_s:
                self.misplaced += 1
                continue
            released.append(item)
            self._released_arrival_s = max(self._released_arrival_s, arrival_s)
            self._mark_released(seq_no)
            self.next_seq = (seq_no + 1) % SEQ_MODULO
        return released

    def flush(self) -> list[T]:
        """Release everything waiting, in order, declaring every gap lost."""
        released: list[T] = []
        while self._waiting and self.next_seq is not None:
            released.extend(self.pop_ready(float("inf")))
        return released
