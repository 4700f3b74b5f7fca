"""The multi-rate executive: periods, phases, priority order, determinism, real-time measures."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

from onboard.runtime import Executive, RealTimeClock, SimClock
from onboard.runtime.clock import NS_PER_S

MS = 1_000_000


def test_same_tick_releases_run_in_priority_order() -> None:
    executive = Executive(SimClock(), record_trace=True)
    order: list[str] = []
    # Registered in the wrong order on purpose: B > C > A as in seed 004.
    executive.add_task("A", lambda _t: order.append("A"), period_s=0.040, priority=1)
    executive.add_task("C", lambda _t: order.append("C"), period_s=0.002, priority=2)
    executive.add_task("B", lambda _t: order.append("B"), period_s=0.002, priority=3)
    executive.run_until(40 * MS)
    assert order[:3] == ["B", "C", "A"]
    assert order[3:5] == ["B", "C"]
    assert order[-3:] == ["B", "C", "A"]
    assert executive.stats["B"].releases == 21
    assert executive.stats["A"].releases == 2


def test_equal_priorities_keep_registration_order() -> None:
    executive = Executive(SimClock(), record_trace=True)
    for name in ("first", "second", "third"):
        executive.add_task(name, lambda _t: None, period_s=0.01)
    executive.run_until(0)
    assert executive.trace == [(0, "first"), (0, "second"), (0, "third")]


def test_periods_and_phases() -> None:
    executive = Executive(SimClock(), record_trace=True)
    executive.add_task("fast", lambda _t: None, period_s=0.010)
    executive.add_task("slow", lambda _t: None, period_s=0.025, phase_s=0.005)
    executive.run_until(60 * MS)
    assert executive.trace is not None
    slow = [t for t, name in executive.trace if name == "slow"]
    fast = [t for t, name in executive.trace if name == "fast"]
    assert slow == [5 * MS, 30 * MS, 55 * MS]
    assert fast == [k * 10 * MS for k in range(7)]
    assert executive.clock.now_ns == 60 * MS


def test_task_receives_its_release_time() -> None:
    executive = Executive(SimClock())
    seen: list[int] = []
    executive.add_task("t", seen.append, period_s=0.1, phase_s=0.05)
    executive.run_for(0.3)
    assert seen == [50 * MS, 150 * MS, 250 * MS]


def _lockstep_run() -> tuple[list[tuple[int, str]], list[float]]:
    """A small closed loop: a plant integrating a controller's output at another rate."""
    executive = Executive(SimClock(), record_trace=True)
    state = {"x": 0.0, "v": 0.0, "u": 0.0}
    outputs: list[float] = []

    def plant(_t: int) -> None:
        state["v"] += (state["u"] - 0.1 * state["v"]) * 0.003
        state["x"] += state["v"] * 0.003

    def controller(_t: int) -> None:
        state["u"] = 2.0 * (10.0 - state["v"]) + 0.01 * (100.0 - state["x"])
        outputs.append(state["x"])

    executive.add_task("plant", plant, period_s=0.003, priority=2)
    executive.add_task("controller", controller, period_s=0.1, phase_s=0.001, priority=1)
    executive.run_for(20.0)
    assert executive.trace is not None
    return executive.trace, outputs


def test_lockstep_runs_are_identical() -> None:
    first_trace, first_outputs = _lockstep_run()
    second_trace, second_outputs = _lockstep_run()
    assert first_trace == second_trace
    assert first_outputs == second_outputs  # bit for bit, not approximately
    assert len(first_outputs) == 200


def test_execution_time_is_recorded() -> None:
    ticks = iter(range(0, 10**9, 7))  # each task body "takes" 7 ns
    executive = Executive(SimClock(), perf_counter_ns=lambda: next(ticks))
    executive.add_task("t", lambda _t: None, period_s=0.01)
    executive.run_for(0.1)
    stats = executive.stats["t"]
    assert stats.releases == 11
    assert stats.exec_max_ns == 7
    assert stats.exec_mean_ns == pytest.approx(7.0)
    assert stats.overruns == 0


class FakeWall:
    """A wall clock that only moves when told to, and when the clock 'sleeps'."""

    def __init__(self) -> None:
        self.ns = 1_000 * NS_PER_S

    def __call__(self) -> int:
        return self.ns


def test_real_time_lateness_and_overruns() -> None:
    wall = FakeWall()
    clock = RealTimeClock(2.0, monotonic_ns=wall)
    executive = Executive(clock, perf_counter_ns=wall)

    def slow_body(_t: int) -> None:
        wall.ns += 80 * MS  # longer than the 100 ms / ×2 = 50 ms wall period

    executive.add_task("slow", slow_body, period_s=0.1)
    executive.run_until(300 * MS)
    stats = executive.stats["slow"]
    assert stats.releases == 4
    assert stats.overruns == 4
    assert stats.lateness_max_ns > 0


def test_real_time_clock_paces_releases() -> None:
    clock = RealTimeClock(50.0)
    executive = Executive(clock)
    executive.add_task("t", lambda _t: None, period_s=0.1)
    started = time.monotonic()
    executive.run_for(2.0)  # 2 s of simulated time at ×50: at least 40 ms of wall time
    assert time.monotonic() - started >= 2.0 / 50.0 - 1e-3
    assert executive.stats["t"].releases == 21


def test_stop_from_another_thread_ends_an_endless_run() -> None:
    executive = Executive(RealTimeClock(1.0))
    executive.add_task("t", lambda _t: None, period_s=0.05)
    stopper = threading.Timer(0.2, executive.stop)
    stopper.start()
    executive.run_until(None)
    assert executive.stopped
    assert executive.stats["t"].releases >= 2


@pytest.mark.parametrize("kwargs", [{"period_s": 0.0}, {"period_s": 0.1, "phase_s": -1.0}])
def test_bad_task_parameters(kwargs: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match="must"):
        Executive(SimClock()).add_task("t", lambda _t: None, **kwargs)


def test_duplicate_task_name() -> None:
    executive = Executive(SimClock())
    executive.add_task("t", lambda _t: None, period_s=0.1)
    with pytest.raises(ValueError, match="already registered"):
        executive.add_task("t", lambda _t: None, period_s=0.1)


def test_a_task_registered_by_a_running_task_takes_its_place_in_the_order() -> None:
    executive = Executive(SimClock(), record_trace=True)

    def register(_t: int) -> None:
        if "late" not in executive.tasks:
            executive.add_task("late", lambda _t: None, period_s=0.01, priority=9)

    executive.add_task("first", register, period_s=0.01, priority=5)
    executive.add_task("second", lambda _t: None, period_s=0.01, priority=1)
    executive.run_until(10 * MS)
    assert executive.trace == [
        (0, "first"),
        (0, "late"),
        (0, "second"),
        (10 * MS, "late"),
        (10 * MS, "first"),
        (10 * MS, "second"),
    ]


def test_a_task_that_raises_leaves_the_others_running() -> None:
    executive = Executive(SimClock(), record_trace=True)

    def fail(_t: int) -> None:
        raise RuntimeError("body failed")

    executive.add_task("ok", lambda _t: None, period_s=0.01, priority=2)
    executive.add_task("fails", fail, period_s=0.01, priority=1)
    with pytest.raises(RuntimeError):
        executive.run_until(0)
    executive.run_until(20 * MS)
    assert executive.trace == [(0, "ok"), (10 * MS, "ok"), (20 * MS, "ok")]


def _sleeper(executive: Executive, released: list[int], *, until_ns: int | None) -> None:
    """A 2 ms task (priority 5) that goes to sleep on its first release."""

    def step(release_ns: int) -> None:
        released.append(release_ns)
        if len(released) == 1:
            executive.sleep("sleeper", until_ns)

    executive.add_task("sleeper", step, period_s=0.002, priority=5)


def test_a_sleeping_task_comes_back_at_the_last_release_before_its_horizon() -> None:
    executive = Executive(SimClock())
    released: list[int] = []
    _sleeper(executive, released, until_ns=9 * MS)
    executive.run_until(14 * MS)
    assert released == [0, 8 * MS, 10 * MS, 12 * MS, 14 * MS]
    assert executive.stats["sleeper"].releases == 5


@pytest.mark.parametrize(("waker_priority", "woken_at_ms"), [(9, 10), (1, 12)])
def test_a_wake_releases_the_sleeper_at_its_next_turn(
    waker_priority: int, woken_at_ms: int
) -> None:
    """Woken at 10 ms by a task that runs before it there: released at 10 ms; by one that
    runs after it: at 12 ms. Its horizon's entry (20 ms) is then dropped."""
    executive = Executive(SimClock(), record_trace=True)
    released: list[int] = []
    _sleeper(executive, released, until_ns=20 * MS)
    seen: list[int] = []

    def waker(release_ns: int) -> None:
        seen.append(executive.last_release_ns(executive.tasks["sleeper"], 0))
        if release_ns == 10 * MS:
            executive.wake("sleeper")

    executive.add_task("waker", waker, period_s=0.010, priority=waker_priority)
    executive.run_until(24 * MS)
    assert released == [0, woken_at_ms * MS, *range((woken_at_ms + 2) * MS, 25 * MS, 2 * MS)]
    assert not executive.asleep("sleeper")
    # Where the sleeper's turn stands while the waker runs: at 10 ms, after it or before it.
    before = waker_priority > 5
    assert seen == [
        (-2 if before else 0) * MS,
        (8 if before else 10) * MS,
        (18 if before else 20) * MS,
    ]


def test_a_task_asleep_until_woken_is_not_released_at_all() -> None:
    executive = Executive(SimClock())
    released: list[int] = []
    _sleeper(executive, released, until_ns=None)
    executive.run_until(100 * MS)
    assert released == [0]
    assert executive.asleep("sleeper")
    executive.wake("sleeper")  # between runs: from the next release after the present
    executive.run_until(104 * MS)
    assert released == [0, 102 * MS, 104 * MS]
