"""``ato bench run``: the whole stack's real-time factor in lockstep, run after run (issue 10).

Each run is a fresh ``ato run SCENARIO --fast --report DIR`` process, as a user starts it: the
factor is the run's own ``real_time_factor`` (simulated over wall seconds from the start of the
run, the trackside's start-up included, the interpreter's imports not). One run says little on
a shared machine, so the bench repeats and prints, per scenario, the factor's median and its
worst and best run beside the target, the runs that passed their expectations, and where the
stepping's wall time went (each task's mean execution time, median over the runs).

Targets: ``bologna-ring`` ≥ 50× with the full stack; ``milano-bologna-low-soc`` ≥ 10× on the
bogie model.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pydantic import ValidationError
from rich.console import Console
from rich.table import Table

from deploy.scenario.kpi_model import Kpis

__all__ = [
    "DEFAULT_SCENARIOS",
    "TARGET_REAL_TIME_FACTORS",
    "RunSample",
    "ScenarioSummary",
    "bench_run",
    "run_once",
    "run_scenario_process",
    "summarise",
]

TARGET_REAL_TIME_FACTORS: dict[str, float] = {
    "bologna-ring": 50.0,
    "milano-bologna-low-soc": 10.0,
}
"""The issue's targets by scenario name (lockstep, these machines)."""
DEFAULT_SCENARIOS = ("bologna-ring", "milano-bologna-low-soc")
TASKS_SHOWN = 6


@dataclass(frozen=True)
class RunSample:
    """One ``ato run`` process: its exit status and, when it wrote one, its ``kpis.json``."""

    scenario: str
    exit_code: int
    kpis: Kpis | None
    error: str = ""
    """The last line of the run's standard error when it wrote no ``kpis.json`` (or why the
    one it wrote was not read)."""

    @property
    def real_time_factor(self) -> float | None:
        return None if self.kpis is None else self.kpis.real_time_factor


@dataclass(frozen=True)
class ScenarioSummary:
    scenario: str
    runs: int
    passed: int
    failed_to_run: int
    factor_median: float | None
    factor_worst: float | None
    factor_best: float | None
    wall_median_s: float | None
    sim_time_s: float | None
    task_mean_us: dict[str, float]
    """Each task's mean execution time, median over the runs [µs], costliest share first."""
    target: float | None

    @property
    def meets_target(self) -> bool | None:
        if self.target is None or self.factor_median is None:
            return None
        return self.factor_median >= self.target


def run_scenario_process(
    scenario: str,
    *,
    seed: int | None = None,
    timeout_s: float = 3600.0,
    python: Path | None = None,
    cwd: Path | None = None,
    env: dict[str, str] | None = None,
) -> tuple[int, str | None, str]:
    """Run ``python -m deploy run SCENARIO --fast`` (the current interpreter by default) in
    ``cwd`` with ``env``: (exit status, the text of its ``kpis.json`` or None, the last line
    of its standard error when it wrote none)."""
    with tempfile.TemporaryDirectory(prefix="ato-bench-run-") as directory:
        command = [str(python or sys.executable), "-m", "deploy", "run", scenario, "--fast"]
        command += ["--report", directory]
        if seed is not None:
            command += ["--seed", str(seed)]
        try:
            finished = subprocess.run(
                command,
                capture_output=True,
                text=True,
                timeout=timeout_s,
                check=False,
                cwd=cwd,
                env=env,
            )
        except subprocess.TimeoutExpired:
            return -1, None, f"no end within {timeout_s:g} s"
        path = Path(directory) / "kpis.json"
        if not path.is_file():
            lines = finished.stderr.strip().splitlines()
            return finished.returncode, None, lines[-1] if lines else ""
        return finished.returncode, path.read_text(encoding="utf-8"), ""


def run_once(scenario: str, *, seed: int | None = None, timeout_s: float = 3600.0) -> RunSample:
    """Run ``ato run SCENARIO --fast`` in a new interpreter and read its ``kpis.json``."""
    exit_code, text, error = run_scenario_process(scenario, seed=seed, timeout_s=timeout_s)
    if text is None:
        return RunSample(scenario, exit_code, None, error)
    try:
        kpis = Kpis.model_validate_json(text)
    except ValidationError as exc:
        reason = f"kpis.json does not match the model: {exc.errors()[0]['msg']}"
        return RunSample(scenario, exit_code, None, reason)
    return RunSample(scenario, exit_code, kpis)


def summarise(scenario: str, samples: Sequence[RunSample]) -> ScenarioSummary:
    """The figures of one scenario's runs (those without ``kpis.json`` count as not run)."""
    ran = [(s, s.kpis) for s in samples if s.kpis is not None]
    factors = [kpis.real_time_factor for _, kpis in ran]
    walls = [kpis.wall_time_s for _, kpis in ran]
    per_task: dict[str, list[float]] = {}
    shares: dict[str, list[float]] = {}
    for _, kpis in ran:
        breakdown = kpis.wall_time_breakdown
        for name, task in ({} if breakdown is None else breakdown.tasks).items():
            per_task.setdefault(name, []).append(task.mean_us)
            shares.setdefault(name, []).append(task.share or 0.0)
    order = sorted(per_task, key=lambda name: -statistics.median(shares[name]))
    return ScenarioSummary(
        scenario=scenario,
        runs=len(samples),
        passed=sum(1 for s, kpis in ran if s.exit_code == 0 and kpis.passed),
        failed_to_run=len(samples) - len(ran),
        factor_median=statistics.median(factors) if factors else None,
        factor_worst=min(factors) if factors else None,
        factor_best=max(factors) if factors else None,
        wall_median_s=statistics.median(walls) if walls else None,
        sim_time_s=ran[0][1].sim_time_s if ran else None,
        task_mean_us={name: statistics.median(per_task[name]) for name in order},
        target=TARGET_REAL_TIME_FACTORS.get(scenario),
    )


def _factor(value: float | None) -> str:
    return "—" if value is None else f"{value:.1f}×"


def _table(summaries: Sequence[ScenarioSummary]) -> Table:
    table = Table(title="Whole stack in lockstep (`ato run --fast`), one process per run")
    for column in (
        "scenario",
        "runs",
        "passed",
        "simulated",
        "wall (median)",
        "factor median",
        "worst",
        "best",
        "target",
    ):
        table.add_column(column, justify="left" if column == "scenario" else "right")
    for summary in summaries:
        verdict = summary.meets_target
        target = (
            "" if summary.target is None else (f"{'✓' if verdict else '✗'} ≥ {summary.target:g}×")
        )
        not_run = f" ({summary.failed_to_run} did not run)" if summary.failed_to_run else ""
        table.add_row(
            summary.scenario,
            str(summary.runs),
            f"{summary.passed}{not_run}",
            "—" if summary.sim_time_s is None else f"{summary.sim_time_s:.0f} s",
            "—" if summary.wall_median_s is None else f"{summary.wall_median_s:.1f} s",
            _factor(summary.factor_median),
            _factor(summary.factor_worst),
            _factor(summary.factor_best),
            target,
        )
    return table


def bench_run(
    scenarios: Sequence[str] = DEFAULT_SCENARIOS,
    *,
    runs: int = 5,
    seed: int | None = None,
    console: Console | None = None,
) -> list[ScenarioSummary]:
    """Run each scenario ``runs`` times, one after the other; print and return the figures."""
    console = console or Console(width=110)
    summaries = []
    for scenario in scenarios:
        samples = []
        for index in range(runs):
            sample = run_once(scenario, seed=seed)
            factor = sample.real_time_factor
            line = f"{scenario} run {index + 1}/{runs}: exit {sample.exit_code}, "
            line += f"{_factor(factor)}" if factor is not None else f"no kpis ({sample.error})"
            console.print(line)
            samples.append(sample)
        summaries.append(summarise(scenario, samples))
    console.print(_table(summaries))
    for summary in summaries:
        shown = list(summary.task_mean_us.items())[:TASKS_SHOWN]
        if shown:
            tasks = ", ".join(f"{name} {mean_us:.1f}" for name, mean_us in shown)
            console.print(f"{summary.scenario}, mean µs per release (median of runs): {tasks}")
    return summaries
