"""``ato bench run --against REF``: the kpis.json comparison, the order of the runs, the ref's
work tree and interpreter on this repository, and a short run of both sides (issue 24).

Performance is never asserted: the factors are the bench's to print."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console
from typer.testing import CliRunner

from deploy.bench.adf_against import (
    LapSample,
    bench_adf_against,
    compare_laps,
    solve_time_figures,
)
from deploy.bench.adf_bench import field_test_lap
from deploy.bench.against import (
    REPOSITORY_ROOT,
    ReferenceTreeError,
    build_environment,
    interleaved,
    interpreter_for,
    reference_side,
    reference_work_tree,
    resolve_commit,
    write_json,
)
from deploy.bench.kpi_diff import ABSENT, WALL_CLOCK_FIELDS, KpiDifference, kpi_differences
from deploy.bench.run_against import SideSample, bench_run_against, compare_scenario
from deploy.cli import app
from deploy.scenario.kpi_model import Kpis
from tests.deploy.kpi_samples import sample_kpis

SCENARIOS = REPOSITORY_ROOT / "deploy" / "scenarios"


def _kpis(**changes: Any) -> dict[str, Any]:
    document: dict[str, Any] = json.loads(sample_kpis(**changes).model_dump_json())
    return document


def _git(*arguments: str) -> str:
    return subprocess.run(
        ["git", "-C", str(REPOSITORY_ROOT), *arguments],
        capture_output=True,
        text=True,
        check=True,
    ).stdout


def _work_trees() -> set[str]:
    listing = _git("worktree", "list", "--porcelain")
    return {line.split(" ", 1)[1] for line in listing.splitlines() if line.startswith("worktree ")}


# --- kpis.json compared -------------------------------------------------------------------


def test_wall_clock_fields_are_not_differences_and_a_real_one_is_reported() -> None:
    tree = _kpis()
    ref = _kpis(
        wall_time_s=99.0,
        real_time_factor=1.2,
        nmpc_ms={"p50": 7.0, "p99": 70.0, "max": 700.0},
        wall_time_breakdown={"lockstep_s": 3.0, "tasks": {}, "executive_and_slices_s": 0.1},
    )
    assert kpi_differences(tree, ref) == []
    ref["stops"][0]["stop_error_m"] = 0.1000001
    ref["etcs_sb_count"] = 1
    assert kpi_differences(tree, ref) == [
        KpiDifference("stops[0].stop_error_m", 0.1, 0.1000001),
        KpiDifference("etcs_sb_count", 0, 1),
    ]


def test_what_one_side_lacks_is_absent_and_true_is_not_one() -> None:
    tree = _kpis()
    ref = _kpis(stops=[], eoa_stops=[])
    del ref["max_jerk_mps3"]
    ref["an_older_field"] = True
    ref["system_decay"] = 0
    found = {d.path: (d.tree, d.ref) for d in kpi_differences(tree, ref)}
    assert found["stops[0]"] == (tree["stops"][0], ABSENT)
    assert found["eoa_stops[0]"] == (tree["eoa_stops"][0], ABSENT)
    assert found["max_jerk_mps3"] == (0.8, ABSENT)
    assert found["an_older_field"] == (ABSENT, True)
    assert found["system_decay"] == (False, 0)
    assert len(found) == 5


def test_an_expectation_judged_on_a_wall_clock_field_is_left_out() -> None:
    judged = [
        {"name": "nmpc_ms.p99 <= 5.0", "ok": True, "detail": "found 3.1"},
        {"name": "stops.count == 1.0", "ok": True, "detail": "found 1"},
    ]
    tree = _kpis(expectations=judged)
    ref = _kpis(expectations=[{**judged[0], "detail": "found 4.2"}, judged[1]])
    assert kpi_differences(tree, ref) == []
    ref["expectations"][1]["ok"] = False
    [difference] = kpi_differences(tree, ref)
    assert difference.path == "expectations[0].ok"  # counted without the wall-clock one


def test_every_field_the_model_measures_in_wall_time_is_listed() -> None:
    measured = {
        name
        for name, field in Kpis.model_fields.items()
        if "wall" in (field.description or "").lower()
    }
    assert measured == set(WALL_CLOCK_FIELDS)


# --- the order of the runs and their comparison ---------------------------------------------


def test_runs_alternate_tree_and_ref_round_after_round() -> None:
    assert interleaved(["ring", "line"], 2) == [
        (0, "ring", "tree"),
        (0, "ring", "ref"),
        (0, "line", "tree"),
        (0, "line", "ref"),
        (1, "ring", "tree"),
        (1, "ring", "ref"),
        (1, "line", "tree"),
        (1, "line", "ref"),
    ]


def test_compare_scenario_gives_ratios_and_each_difference_with_its_rounds() -> None:
    def sample(side: Any, round_index: int, factor: float, **changes: Any) -> SideSample:
        kpis = _kpis(real_time_factor=factor, **changes)
        return SideSample("ring", side, round_index, 0, kpis)

    samples = [
        sample("tree", 0, 40.0),
        sample("ref", 0, 20.0, etcs_sb_count=1),
        sample("tree", 1, 60.0),
        sample("ref", 1, 30.0, etcs_sb_count=1),
        sample("tree", 2, 50.0, max_jerk_mps3=0.9),
        SideSample("ring", "ref", 2, 2, None, "boom"),
        SideSample("other", "tree", 0, 0, _kpis(etcs_eb_count=3)),
    ]
    comparison = compare_scenario("ring", samples)
    assert comparison.tree.factors == [40.0, 60.0, 50.0]
    assert (comparison.tree.median, comparison.ref.median) == (50.0, 25.0)
    assert comparison.ratio_median == pytest.approx(2.0)
    assert comparison.tree.p99 == pytest.approx(40.2)  # the slow tail: 1st percentile
    assert comparison.ref.runs == 3
    assert comparison.compared_rounds == 2  # the ref wrote nothing in round 3
    [(difference, rounds)] = comparison.differences
    assert difference == KpiDifference("etcs_sb_count", 0, 1)
    assert rounds == ["run 1", "run 2"]
    assert comparison.tree.runs_unlike_the_first == {2: ["max_jerk_mps3"]}
    assert comparison.ref.runs_unlike_the_first == {}


def test_the_numbers_are_written_as_strict_json(tmp_path: Path) -> None:
    path = tmp_path / "bench.json"
    write_json(path, {"median": float("nan"), "runs": [1.0, float("inf")]})
    assert json.loads(path.read_text()) == {"median": None, "runs": [1.0, None]}
    assert [p.name for p in tmp_path.iterdir()] == ["bench.json"]


@pytest.mark.e2e
@pytest.mark.parametrize("command", [["run", "vc-B"], ["adf"]])
def test_the_commands_refuse_a_ref_that_names_no_commit(command: list[str]) -> None:
    before = _work_trees()
    result = CliRunner().invoke(app, ["bench", *command, "--against", "no-such-ref-24"])
    assert result.exit_code == 2
    assert "'no-such-ref-24' names no commit" in result.output
    assert _work_trees() == before


# --- the ref's work tree and interpreter, on this repository --------------------------------


@pytest.mark.e2e
def test_the_work_tree_holds_the_ref_and_is_removed_at_the_end() -> None:
    head = _git("rev-parse", "HEAD").strip()
    with reference_work_tree("HEAD") as work_tree:
        assert str(work_tree) in _work_trees()
        assert (work_tree / "pyproject.toml").is_file()
        assert (
            subprocess.run(
                ["git", "-C", str(work_tree), "rev-parse", "HEAD"],
                capture_output=True,
                text=True,
                check=True,
            ).stdout.strip()
            == head
        )
        (work_tree / ".ato").mkdir()  # what a run leaves there goes too
        (work_tree / ".ato" / "left.txt").write_text("x")
    assert not work_tree.exists()
    assert not work_tree.parent.exists()
    assert str(work_tree) not in _work_trees()


@pytest.mark.e2e
@pytest.mark.parametrize("interruption", [KeyboardInterrupt, RuntimeError])
def test_the_work_tree_is_removed_on_ctrl_c_and_on_errors(
    interruption: type[BaseException],
) -> None:
    with pytest.raises(interruption), reference_work_tree("HEAD") as work_tree:
        raise interruption()
    assert not work_tree.exists()
    assert str(work_tree) not in _work_trees()


@pytest.mark.e2e
def test_the_work_tree_is_removed_on_sigterm() -> None:
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("a signal handler is set in the main thread only")
    with pytest.raises(SystemExit) as leaving, reference_work_tree("HEAD") as work_tree:
        os.kill(os.getpid(), signal.SIGTERM)
    assert leaving.value.code == 128 + signal.SIGTERM
    assert not work_tree.exists()
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


@pytest.mark.e2e
def test_a_ref_that_names_no_commit_is_a_clear_error() -> None:
    before = _work_trees()
    with pytest.raises(ReferenceTreeError, match="no-such-ref-24"):
        resolve_commit("no-such-ref-24")
    with pytest.raises(ReferenceTreeError), reference_work_tree("no-such-ref-24"):
        pass
    with pytest.raises(ReferenceTreeError):
        resolve_commit("--all")
    assert _work_trees() == before


@pytest.mark.e2e
def test_the_ref_runs_its_own_code_with_the_current_interpreter() -> None:
    with reference_side("HEAD") as side:
        assert side.python == Path(sys.executable)  # same dependencies: the .venv is reused
        found = subprocess.run(
            [
                str(side.python),
                "-c",
                "import deploy, onboard; print(deploy.__file__, onboard.__file__)",
            ],
            cwd=side.root,
            env=side.environment(),
            capture_output=True,
            text=True,
            check=True,
        ).stdout.split()
        assert all(Path(path).is_relative_to(side.root) for path in found), found


@pytest.mark.e2e
def test_other_dependencies_get_an_environment_of_their_own_built_once(tmp_path: Path) -> None:
    tree_root, work_tree = tmp_path / "tree", tmp_path / "ref"
    tree_root.mkdir()
    work_tree.mkdir()
    (tree_root / "pyproject.toml").write_text('[project]\ndependencies = ["numpy"]\n')
    # No dependency at all: a real environment, built without asking an index.
    (work_tree / "pyproject.toml").write_text("[project]\ndependencies = []\n")
    environments = tmp_path / "envs"
    python = interpreter_for(work_tree, tree_root=tree_root, environments=environments)
    [directory] = environments.iterdir()
    assert python == directory / "bin" / "python"
    assert re.fullmatch(r"[0-9a-f]{16}", directory.name)
    prefix = subprocess.run(
        [str(python), "-c", "import sys; print(sys.prefix)"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert Path(prefix) == directory
    built = {p.name: p.stat().st_mtime_ns for p in directory.iterdir()}
    assert interpreter_for(work_tree, tree_root=tree_root, environments=environments) == python
    assert {p.name: p.stat().st_mtime_ns for p in directory.iterdir()} == built


@pytest.mark.e2e
def test_a_failed_environment_build_leaves_nothing_behind(tmp_path: Path) -> None:
    directory = tmp_path / "envs" / "broken"
    with pytest.raises(ReferenceTreeError, match="could not be built"):
        build_environment(directory, ["not a requirement !!"])
    assert not directory.exists()


# --- both sides end to end ------------------------------------------------------------------


@pytest.mark.scenario
def test_bench_run_against_head_runs_both_sides_with_identical_kpis(tmp_path: Path) -> None:
    # The field test cut to 20 s: the whole stack starts, drives and reports on both sides.
    text = (SCENARIOS / "bologna-ring.toml").read_text()
    short = tmp_path / "short-ring.toml"
    short.write_text(re.sub(r"(?m)^duration_s = .*$", "duration_s = 20.0", text, count=1))
    console = Console(record=True, width=200)
    numbers = tmp_path / "numbers.json"
    [comparison] = bench_run_against(
        "HEAD", [str(short)], runs=1, json_path=numbers, console=console, timeout_s=300.0
    )
    output = console.export_text()
    assert f"{short} tree run 1/1: exit 1" in output  # the cut lap fails its expectations
    assert f"{short} ref run 1/1: exit 1" in output
    assert len(comparison.tree.factors) == len(comparison.ref.factors) == 1
    assert comparison.compared_rounds == 1
    assert comparison.differences == []  # lockstep is deterministic
    assert "identical" in output
    written = json.loads(numbers.read_text())
    assert written["wall_clock_fields"] == list(WALL_CLOCK_FIELDS)
    figures = written["scenarios"][str(short)]
    assert figures["kpi_differences"] == []
    assert figures["ratio_median"] == pytest.approx(comparison.ratio_median)
    assert not any(Path(tree).parent.name.startswith("ato-bench-ref-") for tree in _work_trees())


# --- ato bench adf --against ------------------------------------------------------------------


def _lap(speeds: list[float], arrivals: dict[str, list[float]], **changes: Any) -> dict[str, Any]:
    lap = {
        "solve_times_s": [0.001, 0.002, 0.004],
        "solves": 3,
        "failures": 0,
        "speeds_mps": speeds,
        "arrivals": arrivals,
        "traction_energy_j": 1000.0,
        "wall_s": 1.0,
    }
    return lap | changes


def test_laps_compare_speed_stops_and_solves_against_the_tolerance() -> None:
    tree = _lap([0.0, 1.0, 2.0], {"0": [300.0, 0.1], "1": [550.0, -0.2]})
    same = compare_laps(0, tree, _lap([0.0, 1.0, 2.0], {"0": [300.0, 0.1], "1": [550.0, -0.2]}))
    assert (same.speed_mps, same.stop_position_m, same.arrival_s) == (0.0, 0.0, 0.0)
    assert same.within_tolerance
    close = compare_laps(
        0, tree, _lap([0.0, 1.005, 2.0], {"0": [300.0, 0.105], "1": [550.0, -0.2]})
    )
    assert close.speed_mps == pytest.approx(0.005)
    assert close.stop_position_m == pytest.approx(0.005)
    assert close.within_tolerance
    moved = compare_laps(1, tree, _lap([0.0, 1.0, 2.02], {"0": [301.0, 0.1], "1": [550.0, -0.2]}))
    assert moved.speed_mps == pytest.approx(0.02)
    assert moved.arrival_s == pytest.approx(1.0)
    assert not moved.within_tolerance
    short = compare_laps(
        0, tree, _lap([0.0, 1.0], {"0": [300.0, 0.1]}, solves=2, traction_energy_j=900.0)
    )
    assert short.traction_energy_j == pytest.approx(100.0)
    assert len(short.notes) == 3  # control steps, stops made, solves
    assert not short.within_tolerance


def test_solve_times_are_pooled_over_the_laps_that_ran() -> None:
    laps = [
        LapSample("tree", 0, _lap([0.0], {})),
        LapSample("tree", 1, None, "boom"),
        LapSample("tree", 2, _lap([0.0], {}, solve_times_s=[0.003], solves=1, failures=1)),
    ]
    figures = solve_time_figures(laps)
    assert (figures.laps, figures.solves, figures.failures) == (2, 4, 1)
    assert figures.median_ms == pytest.approx(2.5)
    assert figures.max_ms == pytest.approx(4.0)
    assert solve_time_figures([LapSample("ref", 0, None, "boom")]).median_ms is None


@pytest.mark.scenario
def test_bench_adf_against_head_drives_both_sides_to_the_same_trajectory(tmp_path: Path) -> None:
    console = Console(record=True, width=200)
    numbers = tmp_path / "adf.json"
    comparison = bench_adf_against(
        "HEAD", runs=1, duration_s=20.0, json_path=numbers, console=console, timeout_s=600.0
    )
    output = console.export_text()
    # The lap's solves in this process: the 100 control steps less those that coast (no solve).
    here, _ = field_test_lap("sqpmethod", "energy", duration_s=20.0)
    solves = here.nmpc.solves
    assert solves + here.coast_steps == 100
    assert f"field-test lap tree 1/1: {solves} solves" in output
    assert f"field-test lap ref 1/1: {solves} solves" in output
    assert comparison.tree.solves == comparison.ref.solves == solves
    [trajectory] = comparison.trajectories
    assert trajectory.speed_mps == 0.0  # the same code, deterministic: bit for bit
    assert trajectory.notes == []
    written = json.loads(numbers.read_text())
    assert written["solve_times_ms"]["ref"]["solves"] == solves
    assert written["trajectories"][0]["within_tolerance"] is True


@pytest.mark.scenario
def test_bench_run_without_a_ref_writes_its_numbers_too(tmp_path: Path) -> None:
    numbers = tmp_path / "run.json"
    command = ["bench", "run", "vc-rearm-not-valid", "--runs", "1", "--json", str(numbers)]
    result = CliRunner().invoke(app, command)
    assert result.exit_code == 0, result.output
    [summary] = json.loads(numbers.read_text())["scenarios"]
    assert (summary["scenario"], summary["runs"], summary["passed"]) == ("vc-rearm-not-valid", 1, 1)
