"""`ato run bologna-ring --fast` end to end: trackside, onboard and operator in one process on
real Zenoh sessions, lockstep; the seed 000 field test's KPIs, and determinism."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from deploy.scenario import load_scenario
from deploy.scenario.runner import RunOptions, run_scenario

pytestmark = pytest.mark.e2e

WALL_CLOCK = ("wall_time_s", "real_time_factor", "nmpc_ms", "wall_time_breakdown")
"""Fields that measure the machine, not the run."""


def _run(report: Path) -> dict[str, Any]:
    outcome = run_scenario(load_scenario("bologna-ring"), RunOptions(fast=True, report_dir=report))
    kpis: dict[str, Any] = json.loads((report / "kpis.json").read_text())
    assert kpis["passed"] is outcome.passed
    return kpis


def test_bologna_ring_meets_the_field_test_kpis_and_repeats_exactly(tmp_path: Path) -> None:
    first = _run(tmp_path / "first")
    assert first["passed"], [e for e in first["expectations"] if not e["ok"]]
    assert [stop["name"] for stop in first["stops"]] == ["east", "south", "north"]
    for stop in first["stops"]:
        assert abs(stop["stop_error_m"]) <= 0.5
        assert abs(stop["arrival_error_s"]) <= 2.0
    assert first["max_overspeed_kmh"] <= 0.0
    assert first["etcs_sb_count"] == first["etcs_eb_count"] == first["vc_eb_count"] == 0
    assert first["position_error_m"]["rms"] <= 1.0
    assert first["real_time_factor"] > 0.0
    breakdown = first["wall_time_breakdown"]
    tasks = breakdown["tasks"]
    # The VC is two boards in 2-out-of-2 and its datalog: in lockstep each board's B and C and the
    # pair's voter are one task, vc.tick, released only when an input or a threshold needs it.
    assert {"sfa", "control", "etcs", "vc.tick", "vc0.A", "vc1.A", "vc.datalog"} <= tasks.keys()
    instants = first["sim_time_s"] / 0.002
    assert 0 < tasks["vc.tick"]["releases"] < instants / 2
    assert first["odometry_interval_m"]["outside_max_m"] == 0.0
    assert first["etcs_estimate_error_m"]["max"] > 0.0
    assert (tmp_path / "first" / "vc-datalog.jsonl").stat().st_size > 0
    in_tasks_s = sum(task["total_s"] for task in tasks.values())
    assert 0.0 < in_tasks_s <= breakdown["lockstep_s"] <= first["wall_time_s"]
    telemetry = np.load(tmp_path / "first" / "telemetry.npz")
    assert telemetry["speed_mps"].max() == pytest.approx(40 / 3.6, abs=0.5)
    report = (tmp_path / "first" / "report.html").read_text()
    assert report.count("<img") == 5  # the four plots, and the driven speed beside the optimum
    assert "ETCS interval [m]" in report
    assert "driven / optimum" in report
    _check_the_energy_certificate(first)

    second = _run(tmp_path / "second")
    for key in WALL_CLOCK:
        first.pop(key), second.pop(key)
    assert first == second


def _check_the_energy_certificate(kpis: dict[str, Any]) -> None:
    """kpis.json's energy block (issue 22): every leg driven, its optimum on the plant's truth
    found, and no plan beats it (the optimum is the least any run of that leg in that time can
    take, up to the collocation's grid)."""
    energy = kpis["energy"]
    assert kpis["energy_plan_fallbacks"] == 0
    assert [leg["stop"] for leg in energy["legs"]] == ["east", "south", "north"]
    optimum = sum(leg["optimum_kwh"] for leg in energy["legs"])
    assert energy["optimum_kwh"] == pytest.approx(optimum)
    assert energy["driven_vs_optimum"] == pytest.approx(energy["driven_kwh"] / optimum)
    assert energy["plan_vs_optimum"] == pytest.approx(energy["plan_kwh"] / optimum)
    for leg in energy["legs"]:
        assert leg["driven_kwh"] >= 0.99 * leg["optimum_kwh"]
    # The journey's traction is the run's but for the remote driving before it.
    assert 0.0 < energy["driven_kwh"] < kpis["traction_energy_kwh"]
    assert energy["regenerated_kwh"] is None  # the point mass has no electric braking
