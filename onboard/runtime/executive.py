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

_Entry = tuple[int, int, int, str]
"""A queued release: time [ns], −priority, push order (unique: entries never tie), task name
(the task is looked up at its release: :attr:`Executive.tasks` may be rewired, as benches do)."""


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
        self._queue: list[_Entry] = []
        self._order = 0
        self._stopped = False
        self._real_time = isinstance(clock, RealTimeClock)
        self._measures_lateness = type(clock).lateness_ns is not Clock.lateness_ns
        """Lockstep clocks are never late: their lateness is not asked for in the hot loop."""
        self._speed_factor = clock.speed_factor if isinstance(clock, RealTimeClock) else 1.0
        self._running: _Entry | None = None
        """The release now running (None between releases)."""
        self._sleep_until: dict[str, int | None] = {}
        """Asked by a task during its release: its next release no sooner than this (None:
        none until woken)."""
        self._asleep: dict[str, tuple[int, _Entry | None]] = {}
        """Sleeping tasks: their last release [ns] and their queued entry (if any)."""
        self._stale: set[int] = set()
        """Push orders of queued entries that a wake replaced: dropped when they come up."""

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
        queue, clock = self._queue, self.clock
        while queue and not self._stopped:
            release_ns = queue[0][0]
            if end_ns is not None and release_ns > end_ns:
                break
            clock.advance_to(release_ns)
            self._run_releases(release_ns)
        if end_ns is not None and not self._stopped and end_ns > clock.now_ns:
            clock.advance_to(end_ns)

    def _run_releases(self, release_ns: int) -> None:
        """Run every task released at ``release_ns``, highest priority first.

        The hot loop of a lockstep run (about 1 500 releases per simulated second on a node):
        everything it touches is local, the lateness is read only from a clock that can be
        late, and the finished task goes back into the queue by one ``heapreplace`` instead of
        a pop and a push. The order of releases is the same: entries are ordered by (release,
        −priority, push order), all distinct.
        """
        queue, clock, tasks, all_stats = self._queue, self.clock, self.tasks, self.stats
        perf_counter_ns = self._perf_counter_ns
        late = self._measures_lateness
        trace = self.trace
        stale, asleep, sleep_until = self._stale, self._asleep, self._sleep_until
        while queue and not self._stopped:
            entry = queue[0]
            if entry[0] != release_ns:
                break
            if stale and entry[2] in stale:
                stale.discard(entry[2])
                heapq.heappop(queue)
                continue
            name = entry[3]
            if asleep and name in asleep:
                del asleep[name]  # released at the end of its sleep
            task, stats = tasks[name], all_stats[name]
            lateness = clock.lateness_ns(release_ns) if late else 0
            self._running = entry
            started = perf_counter_ns()
            try:
                task.step(release_ns)
            except BaseException:
                self._discard(entry)
                raise
            finally:
                self._running = None
            elapsed = perf_counter_ns() - started
            stats.releases += 1
            stats.exec_total_ns += elapsed
            if elapsed > stats.exec_max_ns:
                stats.exec_max_ns = elapsed
            if late:
                self._note_lateness(stats, task, lateness, elapsed)
            samples = stats.exec_samples_ns
            if len(samples) < MAX_EXEC_SAMPLES:
                samples.append(elapsed)
            if trace is not None:
                trace.append((release_ns, name))
            self._order += 1
            if sleep_until and name in sleep_until:
                self._requeue_asleep(entry, task, release_ns)
                continue
            following = (release_ns + task.period_ns, -task.priority, self._order, name)
            if queue[0] is entry:
                heapq.heapreplace(queue, following)
            else:  # the body registered a task that now comes first
                self._discard(entry)
                heapq.heappush(queue, following)

    def _note_lateness(self, stats: TaskStats, task: Task, lateness: int, elapsed: int) -> None:
        """A release's lateness, and whether it overran (a clock that can be late only)."""
        if lateness:
            stats.lateness_total_ns += lateness
            if lateness > stats.lateness_max_ns:
                stats.lateness_max_ns = lateness
        if self._real_time and lateness + elapsed > task.period_ns / self._speed_factor:
            # Overrun: the body ended after the wall deadline of the task's next release.
            stats.overruns += 1

    # -- sleeping tasks (lockstep) -------------------------------------------------------------

    def sleep(self, name: str, until_ns: int | None) -> None:
        """From within ``name``'s release: skip its releases until the last one at or before
        ``until_ns`` (None: until woken), or until :meth:`wake`. The task must not depend on
        being released meanwhile: what it would have done there must be nothing at all."""
        self._sleep_until[name] = until_ns

    def _requeue_asleep(self, entry: _Entry, task: Task, release_ns: int) -> None:
        """Replace ``entry`` (just released) by the task's release at the end of the sleep it
        asked for, if any: the last on its grid at or before the horizon, the next at least."""
        until_ns = self._sleep_until.pop(task.name)
        following: _Entry | None = None
        if until_ns is not None:
            period = task.period_ns
            latest = release_ns + (until_ns - release_ns) // period * period
            following = (max(latest, release_ns + period), -task.priority, self._order, task.name)
        self._asleep[task.name] = (release_ns, following)
        queue = self._queue
        if queue[0] is entry:
            heapq.heappop(queue)
        else:  # the body registered a task that now comes first
            self._discard(entry)
        if following is not None:
            heapq.heappush(queue, following)

    def asleep(self, name: str) -> bool:
        return name in self._asleep

    def wake(self, name: str) -> None:
        """Release a sleeping task again from its next release after the one now running
        (after the present instant between releases); no effect on a task awake."""
        slept = self._asleep.pop(name, None)
        if slept is None:
            return
        last_ns, queued = slept
        task = self.tasks[name]
        next_ns = self.next_release_ns(task, last_ns)
        if queued is not None:
            if queued[0] <= next_ns:
                return
            self._stale.add(queued[2])
        self._order += 1
        heapq.heappush(self._queue, (next_ns, -task.priority, self._order, name))

    def next_release_ns(self, task: Task, last_ns: int) -> int:
        """The first release on ``task``'s grid (``last_ns`` plus periods) that is still ahead:
        after the release now running, in the executive's order, or after the present
        instant between releases."""
        running = self._running
        now_ns = running[0] if running is not None else self.clock.now_ns
        period = task.period_ns
        steps = max(1, -(-(now_ns - last_ns) // period))
        candidate = last_ns + steps * period
        if candidate == now_ns and (running is None or -task.priority <= running[1]):
            candidate += period  # at the present instant, but its turn has passed
        return candidate

    def last_release_ns(self, task: Task, anchor_ns: int) -> int:
        """The latest release on ``task``'s grid (``anchor_ns`` plus or minus periods) that
        has had its turn: at or before the release now running, in the executive's order."""
        running = self._running
        now_ns = running[0] if running is not None else self.clock.now_ns
        period = task.period_ns
        latest = anchor_ns + (now_ns - anchor_ns) // period * period
        if latest == now_ns and running is not None and -task.priority > running[1]:
            latest -= period  # its turn at this instant is still to come
        return latest

    def _discard(self, entry: _Entry) -> None:
        """Take a released task's entry out of the queue (wherever it now sits)."""
        queue = self._queue
        for index, queued in enumerate(queue):
            if queued is entry:
                queue[index] = queue[-1]
                queue.pop()
                heapq.heapify(queue)
                return
