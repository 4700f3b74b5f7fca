"""How the three tasks talk: non-blocking mailboxes and queues, and what they carry (seed 004).

Seed 004's tasks share no resources; they exchange messages through non-blocking IPC, and a
task finding no message simply goes on with what it last had. Here:

- a :class:`Mailbox` holds the latest value (overwritten by each post): Task B's
  :class:`SupervisionStatus` for C and A, Task C's :class:`ActuationStatus` for A and B;
- a :class:`MessageQueue` is a bounded FIFO that never blocks and counts what it had to drop:
  the requests A sent (for B to check the responses against), the tachometer frames, the
  balise telegram headers;
- a :class:`Delivery` stamps a message with the simulated time it arrived.

Each task owns its own state; what another task needs it gets only as one of these frozen
messages.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from typing import Generic, NamedTuple, TypeVar

from onboard.etcs.balises import TelegramHeader
from onboard.vc._exceptions import VcInputError
from onboard.vc.fsm import BrakeState, EtcsState, TaskBState
from onboard.vc.messages import DecayReason, EbCondition

__all__ = [
    "ActuationStatus",
    "Delivery",
    "Mailbox",
    "MessageQueue",
    "SupervisionStatus",
    "VcEvent",
    "VcEventKind",
]

T = TypeVar("T")


@dataclass(frozen=True, slots=True)
class Delivery(Generic[T]):
    """A message and the simulated time [s] it arrived."""

    message: T
    arrived_s: float


class Mailbox(Generic[T]):
    """Latest-value channel: a post overwrites, a read does not consume."""

    def __init__(self) -> None:
        self._value: T | None = None
        self.posts = 0
        self.stamp: Callable[[T], T] | None = None
        """While its task sleeps (lockstep, :mod:`onboard.vc.tick`): what a read applies to
        the last value posted (the time of the release that would have reposted it)."""

    def post(self, value: T) -> None:
        self._value = value
        self.posts += 1

    def read(self) -> T | None:
        value, stamp = self._value, self.stamp
        if stamp is None or value is None:
            return value
        return stamp(value)


class MessageQueue(Generic[T]):
    """Bounded FIFO channel: ``put`` never blocks (the oldest is dropped and counted)."""

    def __init__(self, capacity: int = 16) -> None:
        if capacity < 1:
            raise VcInputError(f"a queue needs room for one message, got {capacity}")
        self._items: deque[T] = deque(maxlen=capacity)
        self.capacity = capacity
        self.dropped = 0
        self.on_put: Callable[[], None] | None = None
        """Called after each put (the reader's doorbell, when it sleeps in lockstep)."""

    def put(self, item: T) -> None:
        if len(self._items) == self.capacity:
            self.dropped += 1
        self._items.append(item)
        if self.on_put is not None:
            self.on_put()

    def take_all(self) -> tuple[T, ...]:
        """Everything queued, oldest first; the queue is then empty."""
        if not self._items:
            return ()
        items = tuple(self._items)
        self._items.clear()
        return items

    def __len__(self) -> int:
        return len(self._items)


class SupervisionStatus(NamedTuple):
    """Task B's outputs of one cycle, for Task C and Task A (seed 004: items i–vi and more).

    The two statuses are named tuples, immutable as frozen dataclasses are, and built in a
    quarter of the time: each task builds one every 2 ms cycle."""

    time_s: float
    state: TaskBState
    eb_flag: bool
    """The EB flag: raised by conditions 1–6, latched until the hazard has gone at standstill."""
    eb_conditions: frozenset[EbCondition]
    """The conditions behind the flag since it was raised."""
    live_conditions: frozenset[EbCondition]
    """The conditions that hold in this cycle (a new hazard, even with the flag already up)."""
    system_decay: bool
    decay_reasons: tuple[DecayReason, ...]
    standstill: bool
    odometry_efficient: bool
    speed_mps: float | None
    position_m: float | None
    etcs_isolated: bool
    """The radio relay as re-read on the ETCS digital input."""
    eb_released: bool
    """The EB digital input: valves energised and brake pipe charged."""
    vigilance_confirmed_number: int | None
    """Sequence number of the vigilance request the operator confirmed, if it is current."""
    etcs_isolation_confirmed_number: int | None
    etcs_insertion_confirmed_number: int | None
    eb_rearm_confirmed_number: int | None
    last_balise_header: TelegramHeader | None


class ActuationStatus(NamedTuple):
    """Task C's outputs of one cycle, for Task A and Task B."""

    time_s: float
    brake_state: BrakeState
    etcs_state: EtcsState
    valves_energised: bool
    relay_inserted_commanded: bool
    system_decay: bool
    decay_reasons: tuple[DecayReason, ...]
    consumed_rearm_number: int | None
    """The rearm confirmation (its sequence number) Task C last acted on."""


class VcEventKind(StrEnum):
    EB_CONDITION = "eb_condition"
    """Task B: a condition newly holds (detail: its number)."""
    SYSTEM_DECAY = "system_decay"
    """Task B or C: System Decay (detail: the reason)."""
    EB_COMMANDED = "eb_commanded"
    """Task C: the valves de-energised."""
    EB_REARMED = "eb_rearmed"
    """Task C: the EB input reads "released" again after a rearm."""
    ETCS_ISOLATED = "etcs_isolated"
    ETCS_INSERTED = "etcs_inserted"
    REQUEST_REFUSED = "request_refused"
    """Task C: an operator confirmation that could not be acted on (why in the detail)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class VcEvent:
    """A notification for the log: what happened, when, and on which evidence."""

    time_s: float
    task: str
    kind: VcEventKind
    detail: str
    evidence_s: float | None = None
    """When the evidence reached the VC (a message's arrival, a deadline's expiry) [s]."""
