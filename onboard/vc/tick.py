"""Tasks B and C of every board, and the pair's voter, as one lockstep task that sleeps.

In lockstep, a quiet cycle of Task B or C only reposts its status with a new time
(:mod:`onboard.vc.quiet`). :class:`QuietTick` goes one step further: it releases B and C of each
board and then the voter, in the order their priorities give them (B 30, C 20, voter 15: no
other task of a node sits between), as one task of the executive; after a release in which
every one of them is at a fixed point, it *sleeps*, and is not released again

- until the first instant at which time alone could end a fixed point: a threshold of B or C
  (:attr:`~onboard.vc.quiet.QuietCycles.until_s`), a response's arrival on the link, the relay's
  switching, the brake pipe's recharge reaching the EB input's threshold, a fused speed going
  stale; or
- until an input arrives (its :class:`Doorbell` rings): a request of Task A, a tachometer
  frame, a balise telegram, a fused speed, a response sent on the link, a release of Task A
  (whose state the voter compares).

What a sleeping release would have done is nothing but repost the same statuses with its time:
while asleep, the statuses are read with the time of the last release that would have been
(:attr:`~onboard.vc.ipc.Mailbox.stamp`), and the skipped cycles are counted when it wakes.
Real time keeps the separate 2 ms tasks. The proof that nothing else changes is by test:
``tests/onboard/vc/test_event_driven.py`` (docs/vc.md, "Event-driven in lockstep").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from onboard.runtime import Executive, Task
from onboard.runtime.clock import NS_PER_S
from onboard.vc.config import TIME_TOLERANCE_S
from onboard.vc.ipc import Mailbox

if TYPE_CHECKING:
    from onboard.vc.module import VitalControl
    from onboard.vc.redundancy import TwoOutOfTwo

__all__ = ["Doorbell", "QuietTick"]

TICK_NAME = "vc.tick"

TaskA = tuple[str, Callable[[int], None], float, int]
"""A board's Task A for :meth:`QuietTick.register`: name, step, period [s], priority."""

MARGIN_S = 1e-6
"""How much earlier than a time horizon the tick wakes: waking early costs one release,
waking late would be wrong, and the horizons are floats."""


class Doorbell:
    """Rung by whoever writes a sleeping task's inputs: the task is released again at its
    next instant."""

    __slots__ = ("_executive", "_name", "rings")

    def __init__(self, executive: Executive, name: str) -> None:
        self._executive = executive
        self._name = name
        self.rings = 0

    def ring(self) -> None:
        self.rings += 1
        self._executive.wake(self._name)


class QuietTick:
    """B and C of ``boards`` (then ``pair``'s voter) released as one task, asleep when quiet."""

    def __init__(self, boards: Sequence[VitalControl], *, pair: TwoOutOfTwo | None = None) -> None:
        self.boards = tuple(boards)
        self.pair = pair
        self.slept = 0
        """Releases not made (each one a skipped cycle of every B and C)."""
        self._task: Task | None = None
        self._executive: Executive | None = None
        self._last_ns = 0

    def register(
        self,
        executive: Executive,
        *,
        period_s: float,
        phase_s: float,
        priority: int,
        task_a: Sequence[TaskA],
    ) -> tuple[Task, ...]:
        """Add ``vc.tick`` to ``executive``, then each board's Task A (``task_a``: its name,
        step, period and priority); ring the tick's doorbell on every input of B and after
        every release of A (the voter compares A's state). Returns the tasks."""
        self._executive = executive
        self._task = executive.add_task(
            TICK_NAME, self._release, period_s=period_s, phase_s=phase_s, priority=priority
        )
        doorbell = Doorbell(executive, TICK_NAME)
        for vc in self.boards:
            for queue in vc.task_b.input_queues:
                queue.on_put = doorbell.ring
            vc.hardware.response_link.on_send = doorbell.ring
        self.doorbell = doorbell
        tasks = [self._task]
        for name, step, a_period_s, a_priority in task_a:
            tasks.append(
                executive.add_task(
                    name,
                    self._ringing_after(step),
                    period_s=a_period_s,
                    phase_s=phase_s,
                    priority=a_priority,
                )
            )
        return tuple(tasks)

    def _ringing_after(self, step: Callable[[int], None]) -> Callable[[int], None]:
        def run(release_ns: int) -> None:
            step(release_ns)
            self.doorbell.ring()

        return run

    # -- the release ------------------------------------------------------------------------

    def _release(self, release_ns: int) -> None:
        executive, task = self._executive, self._task
        assert executive is not None
        assert task is not None
        if self._mailboxes_stamped:
            self._wake_up(release_ns, task.period_ns)
        now_s = release_ns / NS_PER_S
        pair, boards = self.pair, self.boards
        for index, vc in enumerate(boards):
            vc.task_b.step(now_s)
            if pair is not None:
                pair.watchdogs[index].kick(now_s)
        for vc in boards:
            vc.task_c.step(now_s)
        if pair is not None:
            pair.step(now_s)
        next_s = (release_ns + task.period_ns) / NS_PER_S
        horizon_s = self.horizon_s(now_s, next_s)
        if horizon_s >= next_s:
            until_ns = (
                None if horizon_s == math.inf else math.floor((horizon_s - MARGIN_S) * NS_PER_S)
            )
            executive.sleep(task.name, until_ns)
            self._last_ns = release_ns
            self._stamp(self._stamped_time)

    def horizon_s(self, now_s: float, next_s: float = -math.inf) -> float:
        """Until when [s] every B, C and the voter stay at their fixed points with no new
        input (−inf: the next cycle may not be quiet); the first horizon found before
        ``next_s`` is returned at once (the tick stays awake whatever the others)."""
        if self.pair is not None and self.pair.disagreeing_since_s is not None:
            return -math.inf
        horizon = math.inf
        for vc in self.boards:
            horizon = min(horizon, vc.task_b.quiet_horizon_s(), vc.task_c.quiet_horizon_s())
            if horizon < next_s:
                return horizon
        for vc in self.boards:
            horizon = min(horizon, _hardware_horizon_s(vc, now_s))
        return horizon

    # -- asleep -----------------------------------------------------------------------------

    @property
    def _mailboxes_stamped(self) -> bool:
        return self.boards[0].task_b.status.stamp is not None

    def _wake_up(self, release_ns: int, period_ns: int) -> None:
        missed = (release_ns - self._last_ns) // period_ns - 1
        self.slept += missed
        for vc in self.boards:
            vc.task_b.quiet.skipped += missed
            vc.task_c.quiet.skipped += missed
        self._stamp(None)

    def _stamp(self, stamp: Callable[[Any], Any] | None) -> None:
        for vc in self.boards:
            mailboxes: tuple[Mailbox[Any], ...] = (vc.task_b.status, vc.task_c.status)
            for mailbox in mailboxes:
                mailbox.stamp = stamp

    def _stamped_time(self, status: Any) -> Any:
        """``status`` as the release that would have been the last reposted it."""
        executive, task = self._executive, self._task
        assert executive is not None
        assert task is not None
        time_s = executive.last_release_ns(task, self._last_ns) / NS_PER_S
        return status if time_s == status.time_s else status._replace(time_s=time_s)


def _hardware_horizon_s(vc: VitalControl, now_s: float) -> float:
    """The first instant [s] after ``now_s`` at which the board's inputs change with time
    alone: a response arrives, the relay switches, the EB input sees the pipe recharged."""
    hardware = vc.hardware
    return min(
        hardware.response_link.next_arrival_s() - TIME_TOLERANCE_S,
        hardware.relay.pending_switch_s() - TIME_TOLERANCE_S,
        hardware.valves.release_change_s(now_s),
    )
