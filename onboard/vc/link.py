"""The VC ↔ ATO-OB link, with fault injection by simulated time (delay, drop, corrupt, freeze).

The ATO-OB and the VC meet only through this link (ARCHITECTURE.md, Messages). A message sent
at ``now_s`` arrives ``delay_s`` later and is handed over by :meth:`FaultyLink.receive` at the
first call at or after that time, so the moment a task sees it depends on simulated time only.

Faults apply to the messages *sent* inside their window ``[start_s, end_s)``:

- DELAY adds ``delay_s`` to their travel time;
- DROP loses them;
- CORRUPT hands them to the link's ``corrupt`` function (for a response: one section's
  sequence number moved, :func:`corrupt_response`);
- FREEZE replaces each by the last message sent before the window (a stuck sender or a
  replaying switch).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Generic, TypeVar

from onboard.vc._exceptions import VcInputError
from onboard.vc.config import TIME_TOLERANCE_S
from onboard.vc.ipc import Delivery
from onboard.vc.messages import AtoObResponse, Section, SectionResponse

__all__ = [
    "FaultyLink",
    "LinkDirection",
    "LinkFault",
    "LinkFaultKind",
    "corrupt_response",
]

T = TypeVar("T")


class LinkFaultKind(StrEnum):
    DELAY = "delay"
    DROP = "drop"
    CORRUPT = "corrupt"
    FREEZE = "freeze"


class LinkDirection(StrEnum):
    REQUEST = "request"
    """VC → ATO-OB."""
    RESPONSE = "response"
    """ATO-OB → VC."""


@dataclass(frozen=True, kw_only=True)
class LinkFault:
    """One fault on one direction of the link, for the messages sent in ``[start_s, end_s)``."""

    direction: LinkDirection
    kind: LinkFaultKind
    start_s: float
    end_s: float = math.inf
    delay_s: float = 0.0
    """DELAY only: the added travel time [s]."""
    section: Section = Section.ATO_VITALITY
    """CORRUPT only: the section whose sequence number is moved."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start_s) and self.end_s > self.start_s):
            raise VcInputError(
                f"a fault window needs start < end, got {self.start_s}, {self.end_s}"
            )
        if not (math.isfinite(self.delay_s) and self.delay_s >= 0):
            raise VcInputError(f"a delay must be finite and not negative, got {self.delay_s}")

    def active(self, now_s: float) -> bool:
        return self.start_s <= now_s < self.end_s


def corrupt_response(response: AtoObResponse, fault: LinkFault) -> AtoObResponse:
    """The response with ``fault.section``'s (one-byte) sequence number moved by two."""
    section = response.section(fault.section)
    moved = SectionResponse((section.sequence_number + 2) % 256, section.answer)
    return response.with_section(fault.section, moved)


class FaultyLink(Generic[T]):
    """One direction of the link: FIFO by arrival time, faults by sending time.

    Parameters
    ----------
    direction
        Which way it carries; the faults of the other direction are ignored.
    delay_s
        Nominal travel time [s].
    faults
        Faults to inject.
    corrupt
        How a CORRUPT fault alters a message; without it CORRUPT drops (as a failed CRC).
    """

    def __init__(
        self,
        direction: LinkDirection,
        *,
        delay_s: float = 0.001,
        faults: Sequence[LinkFault] = (),
        corrupt: Callable[[T, LinkFault], T] | None = None,
    ) -> None:
        if not (math.isfinite(delay_s) and delay_s >= 0):
            raise VcInputError(f"a delay must be finite and not negative, got {delay_s}")
        self.direction = direction
        self.delay_s = delay_s
        self.faults = tuple(f for f in faults if f.direction is direction)
        self._corrupt = corrupt
        self._in_flight: list[tuple[float, int, T]] = []
        self._count = 0
        self._last_sent: T | None = None
        """The last message sent outside a FREEZE window (what a freeze repeats)."""
        self.sent = 0
        self.dropped = 0
        self.delivered = 0
        self.on_send: Callable[[], None] | None = None
        """Called when a message goes in flight (the reader's doorbell, when it sleeps)."""

    def send(self, message: T, now_s: float) -> None:
        """Put ``message`` on the wire at ``now_s``."""
        self.sent += 1
        delay_s = self.delay_s
        for fault in self.faults:
            if not fault.active(now_s):
                continue
            if fault.kind is LinkFaultKind.DROP:
                self.dropped += 1
                return
            if fault.kind is LinkFaultKind.DELAY:
                delay_s += fault.delay_s
            elif fault.kind is LinkFaultKind.FREEZE:
                if self._last_sent is None:
                    self.dropped += 1
                    return
                message = self._last_sent
            elif self._corrupt is None:
                self.dropped += 1
                return
            else:
                message = self._corrupt(message, fault)
        if not any(f.kind is LinkFaultKind.FREEZE and f.active(now_s) for f in self.faults):
            self._last_sent = message
        self._count += 1
        heapq.heappush(self._in_flight, (now_s + delay_s, self._count, message))
        if self.on_send is not None:
            self.on_send()

    def next_arrival_s(self) -> float:
        """When the next message in flight arrives [s] (inf: none in flight)."""
        return self._in_flight[0][0] if self._in_flight else math.inf

    def arrived_by(self, now_s: float) -> bool:
        """Whether :meth:`receive` at ``now_s`` would hand over a message."""
        in_flight = self._in_flight
        return bool(in_flight) and in_flight[0][0] <= now_s + TIME_TOLERANCE_S

    def receive(self, now_s: float) -> tuple[Delivery[T], ...]:
        """The messages arrived by ``now_s``, oldest first, each with its arrival time."""
        if not self._in_flight or self._in_flight[0][0] > now_s + TIME_TOLERANCE_S:
            return ()
        arrived: list[Delivery[T]] = []
        while self._in_flight and self._in_flight[0][0] <= now_s + TIME_TOLERANCE_S:
            arrival_s, _, message = heapq.heappop(self._in_flight)
            arrived.append(Delivery(message, arrival_s))
        self.delivered += len(arrived)
        return tuple(arrived)
