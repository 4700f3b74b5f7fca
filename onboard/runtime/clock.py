"""Clocks for the executive: lockstep simulated time, or wall time times a speed factor.

Simulated time is an integer number of nanoseconds so that periods add up exactly and a lockstep
run is bit-for-bit repeatable. Only the clocks (and the executive's measurements) read the wall
clock; components get ``now`` as an argument.
"""

from __future__ import annotations

import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable

__all__ = ["NS_PER_S", "Clock", "RealTimeClock", "SimClock"]

NS_PER_S = 1_000_000_000


class Clock(ABC):
    """Simulated time, advanced by the executive from one release to the next."""

    def __init__(self) -> None:
        self._now_ns = 0

    @property
    def now_ns(self) -> int:
        return self._now_ns

    @property
    def now_s(self) -> float:
        return self._now_ns / NS_PER_S

    @abstractmethod
    def advance_to(self, t_ns: int) -> int:
        """Move simulated time to ``t_ns``; return the lateness [ns] (0 in lockstep)."""

    def interrupt(self) -> None:  # noqa: B027 - optional hook; lockstep never waits
        """Wake a clock that is waiting, so that the executive can stop promptly."""

    def lateness_ns(self, t_ns: int) -> int:  # noqa: ARG002 - lockstep is never late
        """How late [ns, wall time] it is now for a release due at simulated ``t_ns``."""
        return 0


class SimClock(Clock):
    """Lockstep: time jumps to the next release at once."""

    def advance_to(self, t_ns: int) -> int:
        if t_ns < self._now_ns:
            raise ValueError(f"time cannot go back from {self._now_ns} to {t_ns} ns")
        self._now_ns = t_ns
        return 0


class RealTimeClock(Clock):
    """Paced at wall time × ``speed_factor``; reports how late each release was reached.

    Parameters
    ----------
    speed_factor
        Simulated seconds per wall second (1 for live driving).
    spin_s
        The last part of each wait is spent polling the clock instead of sleeping [s]: the OS
        wakes a sleeper late by tens to hundreds of µs, a poll does not (at the price of a busy
        core). 0 sleeps all the way.
    monotonic_ns
        The wall clock, injectable for tests.
    """

    def __init__(
        self,
        speed_factor: float = 1.0,
        *,
        spin_s: float = 0.0,
        monotonic_ns: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        super().__init__()
        if not speed_factor > 0:
            raise ValueError(f"speed factor must be positive, got {speed_factor}")
        if not 0.0 <= spin_s < 1.0:
            raise ValueError(f"spin time must be in [0, 1) s, got {spin_s}")
        self.speed_factor = speed_factor
        self.spin_ns = round(spin_s * NS_PER_S)
        self._monotonic_ns = monotonic_ns
        self._wall_origin_ns: int | None = None
        self._wake = threading.Event()

    def wall_deadline_ns(self, t_ns: int) -> int:
        if self._wall_origin_ns is None:
            self._wall_origin_ns = self._monotonic_ns() - round(self._now_ns / self.speed_factor)
        return self._wall_origin_ns + round(t_ns / self.speed_factor)

    def advance_to(self, t_ns: int) -> int:
        if t_ns < self._now_ns:
            raise ValueError(f"time cannot go back from {self._now_ns} to {t_ns} ns")
        deadline = self.wall_deadline_ns(t_ns)
        remaining = deadline - self._monotonic_ns()
        if remaining > self.spin_ns and not self._wake.is_set():
            self._wake.wait((remaining - self.spin_ns) / NS_PER_S)
        if self.spin_ns:
            while self._monotonic_ns() < deadline and not self._wake.is_set():
                pass
        self._now_ns = t_ns
        return self.lateness_ns(t_ns)

    def interrupt(self) -> None:
        self._wake.set()

    def lateness_ns(self, t_ns: int) -> int:
        return max(0, self._monotonic_ns() - self.wall_deadline_ns(t_ns))
