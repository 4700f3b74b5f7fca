"""``ato bench run`` reads real runs and summarises them without hiding a failed one (its
figures are printed by the bench, not tested)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

from deploy.bench.run_bench import RunSample, bench_run, run_once, summarise
from deploy.scenario.kpi_model import Kpis
from tests.deploy.kpi_samples import sample_kpis

pytestmark = pytest.mark.scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "deploy" / "scenarios"


def _task(mean_us: float, share: float) -> dict[str, Any]:
    return {"releases": 1000, "total_s": 1.0, "mean_us": mean_us, "share": share}


def _kpis(factor: float, *, passed: bool = True, control_share: float = 0.3) -> Kpis:
    return sample_kpis(
        passed=passed,
        sim_time_s=1000.0,
        wall_time_s=1000.0 / factor,
        real_time_factor=factor,
        wall_time_breakdown={
            "lockstep_s": 900.0 / factor,
            "tasks": {
                "sfa": _task(40.0 + factor, 0.25),
                "control": _task(900.0 + factor, control_share),
            },
            "executive_and_slices_s": 1.0,
        },
    )


def test_summarise_gives_median_worst_best_and_counts_what_did_not_pass_or_run() -> None:
    samples = [
        RunSample("bologna-ring", 0, _kpis(40.0)),
        RunSample("bologna-ring", 0, _kpis(60.0)),
        RunSample("bologna-ring", 1, _kpis(55.0, passed=False)),
        RunSample("bologna-ring", 2, None, "no such scenario"),
    ]
    summary = summarise("bologna-ring", samples)
    assert (summary.runs, summary.passed, summary.failed_to_run) == (4, 2, 1)
    assert summary.factor_median == 55.0
    assert (summary.factor_worst, summary.factor_best) == (40.0, 60.0)
    assert summary.wall_median_s == pytest.approx(1000.0 / 55.0)
    assert summary.target == 50.0
    assert summary.meets_target is True
    assert list(summary.task_mean_us) == ["control", "sfa"]  # the costliest share first
    assert summary.task_mean_us["sfa"] == 95.0
    slower = summarise("bologna-ring", [RunSample("bologna-ring", 0, _kpis(37.0))])
    assert slower.meets_target is False


def test_a_scenario_with_no_run_has_no_figures_and_meets_no_target() -> None:
    summary = summarise("milano-bologna-low-soc", [RunSample("x", 2, None, "boom")])
    assert summary.factor_median is None
    assert summary.meets_target is None
    assert summary.task_mean_us == {}


def test_run_once_reads_a_real_run_and_reports_its_failed_expectations(tmp_path: Path) -> None:
    # The field test cut to 30 s: the whole stack runs, the lap cannot be done, the run fails.
    text = (SCENARIOS / "bologna-ring.toml").read_text()
    short = tmp_path / "short-ring.toml"
    short.write_text(re.sub(r"(?m)^duration_s = .*$", "duration_s = 30.0", text, count=1))
    sample = run_once(str(short), timeout_s=300.0)
    assert sample.kpis is not None, sample.error
    assert sample.exit_code == 1
    assert sample.kpis.passed is False
    assert sample.kpis.sim_time_s == pytest.approx(30.0, abs=0.5)
    assert sample.real_time_factor is not None
    assert sample.real_time_factor > 0
    assert sample.kpis.wall_time_breakdown is not None
    assert "control" in sample.kpis.wall_time_breakdown.tasks
    missing = run_once(str(tmp_path / "no-such.toml"), timeout_s=120.0)
    assert missing.kpis is None
    assert missing.exit_code == 2
    assert missing.error


def test_bench_run_prints_each_run_and_the_table() -> None:
    console = Console(record=True, width=200)
    [summary] = bench_run(["vc-B"], runs=2, console=console)
    assert summary.runs == 2
    assert summary.passed == 2
    assert summary.failed_to_run == 0
    text = console.export_text()
    assert "vc-B run 1/2: exit 0" in text
    assert "vc-B run 2/2: exit 0" in text
    assert "factor median" in text
