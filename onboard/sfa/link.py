"""Fault injection on a datagram link (seed 002 §4.1.1, the online configuration's bus faults).

:class:`FaultyLink` sits between a sender and a receiver, in lockstep or in front of a real
socket: each datagram sent at ``now_s`` is lost, corrupted, duplicated, delayed past its
successors, or delivered after the base latency, as :class:`LinkFaults` says, drawing from one
numpy ``Generator`` so that a seed fixes the outcome. A dead bus delivers nothing in its windows.
"""

from __future__ import annotations

import heapq
import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from onboard.plant.sensors import TimeWindow

__all__ = ["FaultyLink", "LinkFaults"]


@dataclass(frozen=True, kw_only=True)
class LinkFaults:
    """Probabilities per datagram, delays [s] and dead-bus windows."""

    loss_rate: float = 0.0
    reorder_rate: float = 0.0
    reorder_delay_s: float = 0.02
    duplicate_rate: float = 0.0
    corrupt_rate: float = 0.0
    latency_s: float = 0.0
    dead_windows: tuple[TimeWindow, ...] = ()
    faults_from_s: float = 1.0
    faults_until_s: float = math.inf
    """... and sent before this time [s] (a fault window of a scenario)."""
    """Loss, corruption, reordering and duplication hit datagrams sent from this time [s]: the
    GROUND_TRUTH that starts a run is one datagram, and a run whose start is lost never
    initialises (the listener counts its packets as before GROUND_TRUTH)."""

    def __post_init__(self) -> None:
        for name in ("loss_rate", "reorder_rate", "duplicate_rate", "corrupt_rate"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must lie in [0, 1]")
        if self.reorder_delay_s < 0.0 or self.latency_s < 0.0:
            raise ValueError("delays must not be negative")


@dataclass
class FaultyLink:
    """A lossy, reordering, duplicating, corrupting link with delivery times.

    ``send`` schedules; ``deliver(now_s)`` returns the datagrams due by ``now_s`` with their
    delivery times, in delivery order.
    """

    faults: LinkFaults
    rng: np.random.Generator
    counters: Counter[str] = field(default_factory=Counter)
    _queue: list[tuple[float, int, bytes]] = field(default_factory=list)
    _order: int = 0

    @property
    def _random(self) -> bool:
        """Whether any fault needs a draw (without one, no random number is taken)."""
        f = self.faults
        return bool(f.loss_rate or f.corrupt_rate or f.reorder_rate or f.duplicate_rate)

    def _schedule(self, datagram: bytes, at_s: float) -> None:
        heapq.heappush(self._queue, (at_s, self._order, datagram))
        self._order += 1

    def send(self, datagram: bytes, now_s: float) -> None:
        faults = self.faults
        self.counters["sent"] += 1
        if any(window.start_s <= now_s < window.end_s for window in faults.dead_windows):
            self.counters["dead_bus"] += 1
            return
        if not (faults.faults_from_s <= now_s < faults.faults_until_s) or not self._random:
            self._schedule(datagram, now_s + faults.latency_s)
            return
        draws = self.rng.random(4)
        if draws[0] < faults.loss_rate:
            self.counters["lost"] += 1
            return
        if draws[1] < faults.corrupt_rate and datagram:
            corrupted = bytearray(datagram)
            position = int(self.rng.integers(len(corrupted)))
            corrupted[position] ^= int(self.rng.integers(1, 256))
            datagram = bytes(corrupted)
            self.counters["corrupted"] += 1
        at_s = now_s + faults.latency_s
        if draws[2] < faults.reorder_rate:
            at_s += faults.reorder_delay_s * (0.5 + 0.5 * float(self.rng.random()))
            self.counters["delayed"] += 1
        self._schedule(datagram, at_s)
        if draws[3] < faults.duplicate_rate:
            self._schedule(datagram, at_s + faults.reorder_delay_s * float(self.rng.random()))
            self.counters["duplicated"] += 1

    def deliver(self, now_s: float) -> list[tuple[bytes, float]]:
        due: list[tuple[bytes, float]] = []
        queue = self._queue
        while queue and queue[0][0] <= now_s:
            at_s, _, datagram = heapq.heappop(queue)
            due.append((datagram, at_s))
        return due

    def drain(self) -> list[tuple[bytes, float]]:
        """Everything still in flight, in delivery order."""
        return self.deliver(float("inf"))
