"""``ato bench adf --against REF``: the NMPC's solve times on the current tree and on a git ref,
side by side in one sitting (issue 24).

Each lap is ``ato bench adf``'s field-test lap (bologna-ring, three stops, the point-mass plant
with model mismatch, :func:`deploy.bench.adf_bench.field_test_lap`) run by one side's code in a
fresh interpreter of its own (:mod:`deploy.bench.against`), the laps alternating tree, ref,
tree, ref. The driver (:data:`LAP_DRIVER`) calls the side's own ``field_test_lap`` and writes
what the lap recorded as JSON, so that it works on any ref that has that function.

Printed: each side's NMPC solve times over all its laps (median, p99, max, numpy's linear
interpolation, :mod:`deploy.stats`) and the ratios tree/ref (below 1: the tree is faster); then
the closed-loop trajectory of each round, tree against ref: the largest speed difference at the
control steps, the stop positions and arrival times, the traction energy, against the issue's
tolerance (1 cm and 0.01 m/s), and the solves and failures of each side.
"""

from __future__ import annotations

import json
import subprocess
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from deploy.bench.against import (
    ENVIRONMENTS_DIR,
    SIDES,
    Side,
    SideLabel,
    interleaved,
    reference_side,
    tree_over_ref,
    tree_side,
    write_json,
)
from deploy.stats import percentiles

__all__ = [
    "LAP_DRIVER",
    "POSITION_TOLERANCE_M",
    "SPEED_TOLERANCE_MPS",
    "AdfComparison",
    "LapSample",
    "SolveTimeFigures",
    "TrajectoryDifference",
    "bench_adf_against",
    "compare_laps",
    "run_lap",
    "solve_time_figures",
]

SPEED_TOLERANCE_MPS = 0.01
POSITION_TOLERANCE_M = 0.01
"""The issue's "trajectory unchanged": within 1 cm and 0.01 m/s."""

LAP_DRIVER = """\
import json, sys
from deploy.bench.adf_bench import field_test_lap

solver, plan_kind, duration, out = sys.argv[1:5]
options = {} if duration == "full" else {"duration_s": float(duration)}
record, wall_s = field_test_lap(solver, plan_kind, **options)
lap = {
    "solve_times_s": [float(t) for t in record.nmpc.solve_times_s],
    "solves": int(record.nmpc.solves),
    "failures": int(record.nmpc.failures),
    "speeds_mps": [float(v) for v in record.speeds_mps],
    "arrivals": {str(k): [float(t), float(e)] for k, (t, e) in record.arrivals.items()},
    "traction_energy_j": float(record.traction_energy_j),
    "wall_s": float(wall_s),
}
with open(out, "w", encoding="utf-8") as stream:
    json.dump(lap, stream)
"""
"""Run by a side's interpreter in its root: ``-c LAP_DRIVER SOLVER PLAN DURATION|full OUT``."""


@dataclass(frozen=True)
class LapSample:
    """One lap of one side: what it recorded (``LAP_DRIVER``'s JSON), or why there is none."""

    side: SideLabel
    round: int
    lap: dict[str, Any] | None
    error: str = ""


@dataclass(frozen=True)
class SolveTimeFigures:
    """One side's NMPC solve times over all its laps [ms]."""

    laps: int
    solves: int
    failures: int
    median_ms: float | None
    p99_ms: float | None
    max_ms: float | None


@dataclass(frozen=True)
class TrajectoryDifference:
    """One round's lap, tree against ref."""

    round: int
    speed_mps: float
    """Largest |Δ speed| at the control steps both laps have [m/s]."""
    stop_position_m: float
    """Largest |Δ stop error| over the stops both made [m]."""
    arrival_s: float
    """Largest |Δ arrival time| over the stops both made [s]."""
    traction_energy_j: float
    """Δ traction energy, tree − ref [J]."""
    notes: list[str] = field(default_factory=list)
    """What does not compare: control steps or stops only one side has, other solve counts."""

    @property
    def within_tolerance(self) -> bool:
        return (
            not self.notes
            and self.speed_mps <= SPEED_TOLERANCE_MPS
            and self.stop_position_m <= POSITION_TOLERANCE_M
        )


@dataclass(frozen=True)
class AdfComparison:
    tree: SolveTimeFigures
    ref: SolveTimeFigures
    trajectories: list[TrajectoryDifference]
    ratio_median: float | None
    """Median solve time, tree over ref: below 1, the tree is faster."""
    ratio_p99: float | None


def run_lap(
    side: Side,
    *,
    round_index: int,
    solver: str,
    plan_kind: str,
    duration_s: float | None,
    timeout_s: float,
) -> LapSample:
    """One field-test lap with ``side``'s code and interpreter."""
    duration = "full" if duration_s is None else repr(duration_s)
    with tempfile.TemporaryDirectory(prefix="ato-bench-adf-") as directory:
        out = Path(directory) / "lap.json"
        command = [str(side.python), "-c", LAP_DRIVER, solver, plan_kind, duration, str(out)]
        try:
            finished = subprocess.run(
                command,
                cwd=side.root,
                env=side.environment(),
                capture_output=True,
                text=True,
                timeout=timeout_s,
                check=False,
            )
        except subprocess.TimeoutExpired:
            return LapSample(side.label, round_index, None, f"no end within {timeout_s:g} s")
        if finished.returncode != 0 or not out.is_file():
            lines = finished.stderr.strip().splitlines()
            reason = lines[-1] if lines else f"exit {finished.returncode}"
            return LapSample(side.label, round_index, None, reason)
        return LapSample(side.label, round_index, json.loads(out.read_text(encoding="utf-8")))


def solve_time_figures(samples: Sequence[LapSample]) -> SolveTimeFigures:
    """One side's solve times over its laps that ran."""
    laps = [s.lap for s in samples if s.lap is not None]
    times_ms = [1e3 * t for lap in laps for t in lap["solve_times_s"]]
    median, p99, longest = percentiles(times_ms, (50, 99, 100)) if times_ms else (None,) * 3
    return SolveTimeFigures(
        laps=len(laps),
        solves=sum(int(lap["solves"]) for lap in laps),
        failures=sum(int(lap["failures"]) for lap in laps),
        median_ms=median,
        p99_ms=p99,
        max_ms=longest,
    )


def compare_laps(
    round_index: int, tree: dict[str, Any], ref: dict[str, Any]
) -> TrajectoryDifference:
    """The trajectory of one round, tree against ref."""
    notes = []
    speeds = [np.asarray(lap["speeds_mps"], dtype=np.float64) for lap in (tree, ref)]
    common = min(len(s) for s in speeds)
    if len(speeds[0]) != len(speeds[1]):
        notes.append(f"control steps: tree {len(speeds[0])}, ref {len(speeds[1])}")
    speed = float(np.max(np.abs(speeds[0][:common] - speeds[1][:common]), initial=0.0))
    stops = sorted(set(tree["arrivals"]) & set(ref["arrivals"]), key=int)
    if set(tree["arrivals"]) != set(ref["arrivals"]):
        notes.append(f"stops made: tree {sorted(tree['arrivals'])}, ref {sorted(ref['arrivals'])}")
    position = max(
        (abs(tree["arrivals"][k][1] - ref["arrivals"][k][1]) for k in stops), default=0.0
    )
    arrival = max((abs(tree["arrivals"][k][0] - ref["arrivals"][k][0]) for k in stops), default=0.0)
    for key in ("solves", "failures"):
        if tree[key] != ref[key]:
            notes.append(f"{key}: tree {tree[key]}, ref {ref[key]}")
    return TrajectoryDifference(
        round=round_index,
        speed_mps=speed,
        stop_position_m=position,
        arrival_s=arrival,
        traction_energy_j=float(tree["traction_energy_j"] - ref["traction_energy_j"]),
        notes=notes,
    )


def _milliseconds(value: float | None) -> str:
    return "—" if value is None else f"{value:.2f}"


def _table(comparison: AdfComparison, tree: Side, ref: Side, title: str) -> Table:
    table = Table(title=title)
    for column in ("side", "laps", "solves", "failures", "median ms", "p99 ms", "max ms"):
        table.add_column(column, justify="left" if column == "side" else "right")
    for label, side, figures in (("tree", tree, comparison.tree), ("ref", ref, comparison.ref)):
        table.add_row(
            f"{label} ({side.description})",
            str(figures.laps),
            str(figures.solves),
            str(figures.failures),
            _milliseconds(figures.median_ms),
            _milliseconds(figures.p99_ms),
            _milliseconds(figures.max_ms),
        )
    ratio = [
        "—" if r is None else f"{r:.2f}" for r in (comparison.ratio_median, comparison.ratio_p99)
    ]
    table.add_row("tree/ref (below 1: tree faster)", "", "", "", *ratio, "")
    return table


def _print_trajectories(console: Console, trajectories: Sequence[TrajectoryDifference]) -> None:
    for t in trajectories:
        verdict = "within" if t.within_tolerance else "NOT within"
        console.print(
            f"lap {t.round + 1}, tree against ref: speed |Δ| ≤ {t.speed_mps:.3g} m/s, stop "
            f"positions |Δ| ≤ {t.stop_position_m:.3g} m, arrivals |Δ| ≤ {t.arrival_s:.3g} s, "
            f"traction energy Δ {t.traction_energy_j:+.3g} J: {verdict} "
            f"{POSITION_TOLERANCE_M * 100:g} cm and {SPEED_TOLERANCE_MPS:g} m/s"
            + "".join(f"; {note}" for note in t.notes),
            markup=False,
        )


def _report(
    comparison: AdfComparison, tree: Side, ref: Side, lap: dict[str, Any]
) -> dict[str, Any]:
    return {
        "tree": tree.description,
        "ref": ref.description,
        "lap": lap,
        "solve_times_ms": {"tree": vars(comparison.tree), "ref": vars(comparison.ref)},
        "ratio_median": comparison.ratio_median,
        "ratio_p99": comparison.ratio_p99,
        "trajectories": [
            vars(t) | {"within_tolerance": t.within_tolerance} for t in comparison.trajectories
        ],
    }


def bench_adf_against(
    ref: str,
    *,
    runs: int = 3,
    solver: str = "sqpmethod",
    plan_kind: str = "energy",
    duration_s: float | None = None,
    json_path: Path | None = None,
    console: Console | None = None,
    timeout_s: float = 1800.0,
    environments: Path = ENVIRONMENTS_DIR,
) -> AdfComparison:
    """Drive the field-test lap ``runs`` times on the tree and on ``ref``, interleaved (the
    whole lap, or ``duration_s`` of it); print (and write to ``json_path``) and return the
    comparison."""
    console = console or Console(width=130)
    tree = tree_side()
    samples: dict[SideLabel, list[LapSample]] = {side: [] for side in SIDES}
    with reference_side(ref, environments=environments, console=console) as reference:
        sides = {"tree": tree, "ref": reference}
        for round_index, _, label in interleaved(["lap"], runs):
            sample = run_lap(
                sides[label],
                round_index=round_index,
                solver=solver,
                plan_kind=plan_kind,
                duration_s=duration_s,
                timeout_s=timeout_s,
            )
            state = f"{len(sample.lap['solve_times_s'])} solves" if sample.lap else sample.error
            console.print(f"field-test lap {label} {round_index + 1}/{runs}: {state}", markup=False)
            samples[label].append(sample)
    figures = {side: solve_time_figures(samples[side]) for side in SIDES}
    comparison = AdfComparison(
        tree=figures["tree"],
        ref=figures["ref"],
        trajectories=[
            compare_laps(t.round, t.lap, r.lap)
            for t, r in zip(samples["tree"], samples["ref"], strict=True)
            if t.lap is not None and r.lap is not None
        ],
        ratio_median=tree_over_ref(figures["tree"].median_ms, figures["ref"].median_ms),
        ratio_p99=tree_over_ref(figures["tree"].p99_ms, figures["ref"].p99_ms),
    )
    title = f"NMPC solve times on the field-test lap ({solver}, {plan_kind} plan), side by side"
    console.print(_table(comparison, tree, reference, title))
    _print_trajectories(console, comparison.trajectories)
    if json_path is not None:
        lap = {"solver": solver, "plan": plan_kind, "duration_s": duration_s, "runs": runs}
        write_json(json_path, _report(comparison, tree, reference, lap))
        console.print(f"numbers written to {json_path}", markup=False)
    return comparison
