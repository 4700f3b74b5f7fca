"""``ato bench vc``: the Vital Control's three tasks, their cost and their timeliness (issue 7).

Tasks A, B and C of one :class:`~onboard.vc.VitalControl` run with the
:class:`~onboard.vc.AtoObResponder` double answering and a train standing still feeding the
tachometer board:

1. in lockstep (:class:`~onboard.runtime.SimClock`) for 10⁶ runs of Task B (2000 s simulated):
   execution time per task (median, p99, max), which does not depend on pacing, every cycle a
   full one as in real time; then the same event-driven, as a lockstep run has them (Tasks B
   and C skip their quiet cycles, :mod:`onboard.vc.quiet`, released as one task that sleeps
   while they are quiet, :mod:`onboard.vc.tick`);
2. in real time (:class:`~onboard.runtime.RealTimeClock`, speed 1) for ``seconds`` (60 by
   default), once sleeping until each release and once polling the clock for its last 500 µs:
   lateness of each release against wall time (p50, p99, max) and deadline misses (lateness +
   execution time over the 2 ms deadline, the seeds' deadline for all three).

The seeds measured WCETs of 20/24/31 µs on their target; ours are Python on a desktop OS.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

from rich.console import Console
from rich.table import Table

from deploy.bench.vc_responder import AtoObResponder
from deploy.stats import percentiles
from onboard.runtime import Clock, Executive, RealTimeClock, SimClock
from onboard.runtime.clock import NS_PER_S
from onboard.runtime.executive import StepFunction
from onboard.vc import Delivery, TachometerBoard, VcConfig, VcHardware, VitalControl

__all__ = ["DEADLINE_S", "TaskTiming", "bench_vc"]

DEADLINE_S = 0.002
"""The seeds' deadline of Tasks A, B and C [s]."""
VC_TASKS = ("vc.B", "vc.C", "vc.tick", "vc.A")
"""Every cycle a full one: B, C and A; event-driven: B and C as ``vc.tick``, and A."""


@dataclass
class TaskTiming:
    """Wall-time samples of one task [ns]."""

    execution_ns: list[int] = field(default_factory=list)
    lateness_ns: list[int] = field(default_factory=list)
    deadline_misses: int = 0

    @property
    def runs(self) -> int:
        return len(self.execution_ns)


def _median_p99_max(samples_ns: list[int]) -> tuple[float, ...]:
    """Median, p99 and maximum [ns]; zeros for a task that never ran."""
    return percentiles(samples_ns, (50, 99, 100)) if samples_ns else (0.0, 0.0, 0.0)


class _StandingTrain:
    def __init__(self, hardware: VcHardware) -> None:
        self.hardware = hardware
        self.board = TachometerBoard(metres_per_pulse=VcConfig().metres_per_pulse)

    def step_ns(self, release_ns: int) -> None:
        now_s = release_ns / NS_PER_S
        frame = self.board.poll(now_s, 0.0)
        if frame is not None:
            self.hardware.tachometer_frames.put(Delivery(frame, now_s))


def _instrument(executive: Executive, clock: Clock) -> dict[str, TaskTiming]:
    """Wrap the VC tasks' bodies to sample their lateness and execution time."""
    timings = {name: TaskTiming() for name in VC_TASKS if name in executive.tasks}
    deadline_ns = round(DEADLINE_S * NS_PER_S)
    for name, timing in timings.items():
        task = executive.tasks[name]

        def timed(
            release_ns: int, step: StepFunction = task.step, timing: TaskTiming = timing
        ) -> None:
            lateness = clock.lateness_ns(release_ns)
            started = time.perf_counter_ns()
            step(release_ns)
            elapsed = time.perf_counter_ns() - started
            timing.execution_ns.append(elapsed)
            timing.lateness_ns.append(lateness)
            if lateness + elapsed > deadline_ns:
                timing.deadline_misses += 1

        executive.tasks[name] = replace(task, step=timed)
    return timings


def _run(
    clock: Clock, seconds: float, *, event_driven: bool = False
) -> tuple[dict[str, TaskTiming], VitalControl, float]:
    """One VC, its ATO-OB double and a standing train for ``seconds`` of ``clock``'s time;
    every cycle a full one unless ``event_driven`` (Tasks B and C skip their quiet cycles)."""
    hardware = VcHardware.emulated()
    vc = VitalControl(hardware)
    executive = Executive(clock)
    executive.add_task("train", _StandingTrain(hardware).step_ns, period_s=0.002, priority=40)
    vc.register(executive, event_driven=event_driven)
    responder = AtoObResponder(hardware.request_link, hardware.response_link)
    executive.add_task("ato_ob", responder.step_ns, period_s=0.002, priority=0)
    timings = _instrument(executive, clock)
    started = time.perf_counter()
    executive.run_for(seconds)
    return timings, vc, time.perf_counter() - started


def _table(title: str, timings: dict[str, TaskTiming], *, lateness: bool) -> Table:
    table = Table(title=title)
    columns = ["task", "runs", "exec median", "exec p99", "exec max"]
    if lateness:
        columns += ["late p50", "late p99", "late max", "deadline misses"]
    for column in columns:
        table.add_column(column, justify="left" if column == "task" else "right")
    for name, timing in timings.items():
        samples = [timing.execution_ns] + ([timing.lateness_ns] if lateness else [])
        values = [value for sample in samples for value in _median_p99_max(sample)]
        row = [name, str(timing.runs), *(f"{value / 1e3:.1f} µs" for value in values)]
        if lateness:
            row.append(str(timing.deadline_misses))
        table.add_row(*row)
    return table


def bench_vc(
    *,
    seconds: float = 60.0,
    execution_runs: int = 1_000_000,
    spins_us: tuple[float, ...] = (0.0, 500.0),
    width: int = 130,
) -> dict[str, dict[str, TaskTiming]]:
    """Execution time over ``execution_runs`` runs of Task B in lockstep, then lateness in real
    time for ``seconds`` with each way of waiting (``spins_us``: the last µs polled, 0 sleeps
    all the way); prints the tables, returns the samples by phase."""
    console = Console(width=width)
    results: dict[str, dict[str, TaskTiming]] = {}
    if execution_runs > 0:
        lockstep_s = execution_runs * DEADLINE_S
        timings, _, wall_s = _run(SimClock(), lockstep_s)
        results["lockstep"] = timings
        title = (
            f"VC execution time in lockstep: {lockstep_s:g} s simulated in {wall_s:.1f} s "
            f"wall (Python, this machine; the seeds' WCET A/B/C: 20/24/31 µs)"
        )
        console.print(_table(title, timings, lateness=False))
        timings, vc, wall_s = _run(SimClock(), lockstep_s, event_driven=True)
        results["lockstep, event-driven"] = timings
        skipped = vc.task_b.quiet.skipped, vc.task_c.quiet.skipped
        slept = vc.tick.slept if vc.tick is not None else 0
        title = (
            f"The same, event-driven as in any lockstep run (B and C as vc.tick): {wall_s:.1f} s "
            f"wall; quiet cycles skipped: B {skipped[0]}, C {skipped[1]}, of which not "
            f"released at all: {slept}"
        )
        console.print(_table(title, timings, lateness=False))
    for spin_us in spins_us:
        clock = RealTimeClock(1.0, spin_s=spin_us / 1e6)
        timings, vc, wall_s = _run(clock, seconds)
        results[f"real time, spin {spin_us:g} µs"] = timings
        how = "sleeping until each release" if spin_us == 0 else f"polling the last {spin_us:g} µs"
        title = (
            f"VC in real time, {how}: {seconds:g} s simulated, {wall_s:.1f} s wall; "
            f"deadline {DEADLINE_S * 1e3:g} ms"
        )
        console.print(_table(title, timings, lateness=True))
        outputs = vc.outputs
        console.print(
            f"EB commanded at the end: {outputs.eb_commanded}; System Decay: {outputs.system_decay}"
        )
    return results
