"""The multi-rate executive: runs registered tasks by period, phase and priority.

Tasks released at the same simulated instant run in decreasing priority, then in registration
order (the Vital Control's B > C > A of seed 004 relies on it). Each task's execution time is
measured; under a :class:`~onboard.runtime.clock.RealTimeClock` its lateness and overruns are
measured too. With a :class:`~onboard.runtime.clock.SimClock` a run is deterministic: the same
tasks give the same release sequence, which :attr:`Executive.trace` records when asked.
"""

from __future__ import annotations

import heapq
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from onboard.runtime.clock import NS_PER_S, Clock, RealTimeClock

__all__ = ["Executive", "Task", "TaskStats"]

StepFunction = Callable[[int], None]
"""A task body: called with the simulated release time [ns]."""


@dataclass(frozen=True)
class Task:
    name: str
    period_ns: int
    phase_ns: int
    priority: int
    step: StepFunction


@dataclass
class TaskStats:
    """Execution record of one task; times in nanoseconds of wall time."""

    releases: int = 0
    exec_total_ns: int = 0
    exec_max_ns: int = 0
    lateness_max_ns: int = 0
    lateness_total_ns: int = 0
    overruns: int = 0
    exec_samples_ns: list[int] = field(default_factory=list, repr=False)

    @property
    def exec_mean_ns(self) -> float:
        return self.exec_total_ns / self.releases if self.releases else 0.0

    @property
    def lateness_mean_ns(self) -> float:
        return self.lateness_total_ns / self.releases if self.releases else 0.0


MAX_EXEC_SAMPLES = 100_000


class Executive:
    """Releases tasks on a clock until told to stop or until an end time.

    Parameters
    ----------
    clock
        Lockstep or real-time clock.
    record_trace
        Keep ``(release_ns, task name)`` of every release in :attr:`trace`.
    perf_counter_ns
        The clock used to time task bodies, injectable for tests.
    """

    def __init__(
        self,
        clock: Clock,
        *,
        record_trace: bool = False,
        perf_counter_ns: Callable[[], int] = time.perf_counter_ns,
    ) -> None:
        self.clock = clock
        self.tasks: dict[str, Task] = {}
        self.stats: dict[str, TaskStats] = {}
        self.trace: list[tuple[int, str]] | None = [] if record_trace else None
        self._perf_counter_ns = perf_counter_ns
        self._queue: list[tuple[int, int, int, str]] = []
        self._order = 0
        self._stopped = False
        self._real_time = isinstance(clock, RealTimeClock)
        self._speed_factor = clock.speed_factor if isinstance(clock, RealTimeClock) else 1.0

    def add_task(
        self,
        name: str,
        step: StepFunction,
        *,
        period_s: float,
        phase_s: float = 0.0,
        priority: int = 0,
    ) -> Task:
        """Register ``step`` to run every ``period_s`` from ``phase_s`` after now."""
        if name in self.tasks:
            raise ValueError(f"task {name!r} already registered")
        period_ns = round(period_s * NS_PER_S)
        phase_ns = round(phase_s * NS_PER_S)
        if period_ns <= 0:
            raise ValueError(f"task {name!r}: period must be positive, got {period_s} s")
        if phase_ns < 0:
            raise ValueError(f"task {name!r}: phase must not be negative, got {phase_s} s")
        task = Task(name, period_ns, phase_ns, priority, step)
        self.tasks[name] = task
        self.stats[name] = TaskStats()
        self._push(self.clock.now_ns + phase_ns, task)
        return task

    def _push(self, release_ns: int, task: Task) -> None:
        self._order += 1
        heapq.heappush(self._queue, (release_ns, -task.priority, self._order, task.name))

    def stop(self) -> None:
        """Ask the run loop to return after the task now running; safe from any thread."""
        self._stopped = True
        self.clock.interrupt()

    @property
    def stopped(self) -> bool:
        return self._stopped

    def run_for(self, duration_s: float) -> None:
        self.run_until(self.clock.now_ns + round(duration_s * NS_PER_S))

    def run_until(self, end_ns: int | None = None) -> None:
        """Run releases up to and including ``end_ns`` (forever if ``None``) or until stopped."""
        queue, tasks, clock = self._queue, self.tasks, self.clock
        while queue and not self._stopped:
            release_ns = queue[0][0]
            if end_ns is not None and release_ns > end_ns:
                break
            clock.advance_to(release_ns)
            while queue and queue[0][0] == release_ns and not self._stopped:
                _, _, _, name = heapq.heappop(queue)
                task = tasks[name]
                self._run(task, release_ns)
                self._order += 1
                heapq.heappush(
                    queue, (release_ns + task.period_ns, -task.priority, self._order, name)
                )
        if end_ns is not None and not self._stopped and end_ns > clock.now_ns:
            clock.advance_to(end_ns)

    def _run(self, task: Task, release_ns: int) -> None:
        stats = self.stats[task.name]
        lateness = self.clock.lateness_ns(release_ns)
        started = self._perf_counter_ns()
        task.step(release_ns)
        elapsed = self._perf_counter_ns() - started
        stats.releases += 1
        stats.exec_total_ns += elapsed
        if elapsed > stats.exec_max_ns:
            stats.exec_max_ns = elapsed
        if lateness:
            stats.lateness_total_ns += lateness
            if lateness > stats.lateness_max_ns:
                stats.lateness_max_ns = lateness
        if self._real_time and lateness + elapsed > task.period_ns / self._speed_factor:
            # Overrun: the body ended after the wall deadline of the task's next release.
            stats.overruns += 1
        samples = stats.exec_samples_ns
        if len(samples) < MAX_EXEC_SAMPLES:
            samples.append(elapsed)
        if self.trace is not None:
            self.trace.append((release_ns, task.name))
