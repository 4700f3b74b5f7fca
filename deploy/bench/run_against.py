"""``ato bench run --against REF``: the whole stack's real-time factor on the current tree and
on a git ref, side by side in one sitting (issue 24).

Each run is a fresh ``python -m deploy run SCENARIO --fast`` process of one side
(:mod:`deploy.bench.against`: the ref in a temporary work tree with its own interpreter), and
the runs alternate, round after round: scenario 1 on the tree, on the ref, scenario 2 on the
tree, on the ref, and again. For each scenario the bench prints each side's median factor and
its slow tail, the factor that 99 % of the runs reach (its 1st percentile: the p99 of the wall
time per simulated second, numpy's linear interpolation, :mod:`deploy.stats`), and the ratios
tree/ref (above 1: the tree is faster). It then compares the two sides' ``kpis.json`` of each
round (:mod:`deploy.bench.kpi_diff`, wall-clock fields left out) and prints every difference,
and checks that each side's runs agree among themselves (lockstep is deterministic).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
from deploy.bench.kpi_diff import (
    WALL_CLOCK_FIELDS,
    KpiDifference,
    grouped_differences,
    kpi_differences,
    shown,
)
from deploy.bench.run_bench import DEFAULT_SCENARIOS, run_scenario_process
from deploy.stats import percentiles

__all__ = [
    "SLOW_TAIL_PERCENTILE",
    "ScenarioComparison",
    "SideFactors",
    "SideSample",
    "bench_run_against",
    "compare_scenario",
    "run_side_once",
    "side_factors",
]

SLOW_TAIL_PERCENTILE = 1.0
"""The factor's percentile printed as its "p99": the factor 99 % of the runs reach."""
VALUE_WIDTH = 100


@dataclass(frozen=True)
class SideSample:
    """One run of one side: its exit status and, when it wrote one, its ``kpis.json`` as JSON."""

    scenario: str
    side: SideLabel
    round: int
    exit_code: int
    kpis: dict[str, Any] | None
    error: str = ""

    @property
    def real_time_factor(self) -> float | None:
        value = None if self.kpis is None else self.kpis.get("real_time_factor")
        return float(value) if isinstance(value, int | float) else None


@dataclass(frozen=True)
class SideFactors:
    """One side's real-time factors on one scenario."""

    runs: int
    passed: int
    factors: list[float]
    """The factor of each run that wrote one, in the order run."""
    median: float | None
    p99: float | None
    """The slow tail: the :data:`SLOW_TAIL_PERCENTILE` percentile of the factors."""
    runs_unlike_the_first: dict[int, list[str]] = field(default_factory=dict)
    """Round → the paths where that run's ``kpis.json`` differs from the side's first run."""


@dataclass(frozen=True)
class ScenarioComparison:
    scenario: str
    tree: SideFactors
    ref: SideFactors
    compared_rounds: int
    """Rounds in which both sides wrote ``kpis.json``."""
    differences: list[tuple[KpiDifference, list[str]]]
    """Each distinct tree/ref difference, with the rounds (``run 2``) it was found in."""
    ratio_median: float | None
    """Median factor, tree over ref: above 1, the tree is faster."""
    ratio_p99: float | None


def run_side_once(
    side: Side, scenario: str, *, round_index: int, seed: int | None, timeout_s: float
) -> SideSample:
    """One ``ato run --fast`` of ``scenario`` with ``side``'s code and interpreter."""
    exit_code, text, error = run_scenario_process(
        _scenario_argument(scenario),
        seed=seed,
        timeout_s=timeout_s,
        python=side.python,
        cwd=side.root,
        env=side.environment(),
    )
    kpis: dict[str, Any] | None = None
    if text is not None:
        try:
            loaded = json.loads(text)
        except ValueError as exc:
            error = f"kpis.json is not JSON: {exc}"
        else:
            kpis = loaded if isinstance(loaded, dict) else None
            error = "" if kpis is not None else "kpis.json is not an object"
    return SideSample(scenario, side.label, round_index, exit_code, kpis, error)


def side_factors(samples: Sequence[SideSample]) -> SideFactors:
    """The figures of one side's runs of one scenario (in the order run)."""
    factors = [f for f in (s.real_time_factor for s in samples) if f is not None]
    written = [(s, s.kpis) for s in samples if s.kpis is not None]
    unlike: dict[int, list[str]] = {}
    for sample, kpis in written[1:]:
        paths = [d.path for d in kpi_differences(written[0][1], kpis)]
        if paths:
            unlike[sample.round] = paths
    median, slow = percentiles(factors, (50, SLOW_TAIL_PERCENTILE)) if factors else (None, None)
    return SideFactors(
        runs=len(samples),
        passed=sum(1 for s, kpis in written if s.exit_code == 0 and kpis.get("passed") is True),
        factors=factors,
        median=median,
        p99=slow,
        runs_unlike_the_first=unlike,
    )


def compare_scenario(scenario: str, samples: Sequence[SideSample]) -> ScenarioComparison:
    """Both sides' figures on ``scenario`` and the differences of their ``kpis.json``, round
    by round."""
    mine = [s for s in samples if s.scenario == scenario]
    by_side = {side: [s for s in mine if s.side == side] for side in SIDES}
    pairs = []
    for tree in by_side["tree"]:
        ref = next((s for s in by_side["ref"] if s.round == tree.round), None)
        if tree.kpis is not None and ref is not None and ref.kpis is not None:
            pairs.append((f"run {tree.round + 1}", kpi_differences(tree.kpis, ref.kpis)))
    figures = {side: side_factors(by_side[side]) for side in SIDES}
    return ScenarioComparison(
        scenario=scenario,
        tree=figures["tree"],
        ref=figures["ref"],
        compared_rounds=len(pairs),
        differences=grouped_differences(pairs),
        ratio_median=tree_over_ref(figures["tree"].median, figures["ref"].median),
        ratio_p99=tree_over_ref(figures["tree"].p99, figures["ref"].p99),
    )


def _factor(value: float | None) -> str:
    return "—" if value is None else f"{value:.1f}×"


def _ratio(value: float | None) -> str:
    return "—" if value is None else f"{value:.2f}"


def _table(comparisons: Sequence[ScenarioComparison], tree: Side, ref: Side) -> Table:
    table = Table(
        title=f"Real-time factor in lockstep: tree ({tree.description}) against "
        f"ref ({ref.description})"
    )
    for column in (
        "scenario",
        "runs",
        "passed",
        "tree median",
        "tree p99",
        "ref median",
        "ref p99",
        "ratio median",
        "ratio p99",
        "kpis.json",
    ):
        if column == "scenario":
            longest = max((len(c.scenario) for c in comparisons), default=8)
            table.add_column(column, overflow="fold", min_width=min(longest, 40))
        else:
            table.add_column(column, justify="right")
    for c in comparisons:
        if not c.compared_rounds:
            verdict = "—"
        elif c.differences:
            verdict = f"{len(c.differences)} differences"
        else:
            verdict = "identical"
        table.add_row(
            c.scenario,
            f"{len(c.tree.factors)}/{len(c.ref.factors)}",
            f"{c.tree.passed}/{c.ref.passed}",
            _factor(c.tree.median),
            _factor(c.tree.p99),
            _factor(c.ref.median),
            _factor(c.ref.p99),
            _ratio(c.ratio_median),
            _ratio(c.ratio_p99),
            verdict,
        )
    return table


def _print_differences(console: Console, comparisons: Sequence[ScenarioComparison]) -> None:
    console.print(
        "runs: those that wrote kpis.json, tree/ref; p99: the factor 99 % of the runs reach; "
        "ratio: tree/ref, above 1 the tree is faster. kpis.json compared without "
        f"{', '.join(WALL_CLOCK_FIELDS)}.",
        markup=False,
    )
    for c in comparisons:
        for label, figures in (("tree", c.tree), ("ref", c.ref)):
            for round_index, paths in figures.runs_unlike_the_first.items():
                console.print(
                    f"{c.scenario}: the {label}'s run {round_index + 1} differs from its first "
                    f"run (not deterministic?) at {', '.join(paths)}",
                    markup=False,
                )
        if c.differences:
            console.print(f"{c.scenario}: kpis.json, tree against ref:", markup=False)
        for difference, rounds in c.differences:
            console.print(
                f"  {difference.path}: tree {shown(difference.tree, VALUE_WIDTH)}, "
                f"ref {shown(difference.ref, VALUE_WIDTH)} ({', '.join(rounds)})",
                markup=False,
            )


def _report(comparisons: Sequence[ScenarioComparison], tree: Side, ref: Side) -> dict[str, Any]:
    """The numbers as ``--json`` writes them."""

    def side(figures: SideFactors) -> dict[str, Any]:
        return {
            "runs": figures.runs,
            "passed": figures.passed,
            "factors": figures.factors,
            "median": figures.median,
            "p99": figures.p99,
            "runs_unlike_the_first": {
                str(r + 1): p for r, p in figures.runs_unlike_the_first.items()
            },
        }

    return {
        "tree": tree.description,
        "ref": ref.description,
        "p99_percentile_of_factor": SLOW_TAIL_PERCENTILE,
        "wall_clock_fields": list(WALL_CLOCK_FIELDS),
        "scenarios": {
            c.scenario: {
                "tree": side(c.tree),
                "ref": side(c.ref),
                "ratio_median": c.ratio_median,
                "ratio_p99": c.ratio_p99,
                "compared_rounds": c.compared_rounds,
                "kpi_differences": [
                    {"path": d.path, "tree": shown(d.tree), "ref": shown(d.ref), "rounds": r}
                    for d, r in c.differences
                ],
            }
            for c in comparisons
        },
    }


def _scenario_argument(scenario: str) -> str:
    """A scenario file by its absolute path (the ref runs in another directory); a name as is."""
    path = Path(scenario)
    return str(path.resolve()) if path.is_file() else scenario


def bench_run_against(
    ref: str,
    scenarios: Sequence[str] = DEFAULT_SCENARIOS,
    *,
    runs: int = 5,
    seed: int | None = None,
    json_path: Path | None = None,
    console: Console | None = None,
    timeout_s: float = 3600.0,
    environments: Path = ENVIRONMENTS_DIR,
) -> list[ScenarioComparison]:
    """Run each scenario ``runs`` times on the tree and on ``ref``, interleaved; print (and
    write to ``json_path``) and return the comparison."""
    console = console or Console(width=130)
    tree = tree_side()
    samples = []
    with reference_side(ref, environments=environments, console=console) as reference:
        console.print(f"tree: {tree.description}; ref: {reference.description}", markup=False)
        sides = {"tree": tree, "ref": reference}
        for round_index, scenario, label in interleaved(scenarios, runs):
            sample = run_side_once(
                sides[label],
                scenario,
                round_index=round_index,
                seed=seed,
                timeout_s=timeout_s,
            )
            factor = sample.real_time_factor
            line = f"{scenario} {label} run {round_index + 1}/{runs}: exit {sample.exit_code}, "
            line += _factor(factor) if factor is not None else f"no kpis ({sample.error})"
            console.print(line, markup=False)
            samples.append(sample)
    comparisons = [compare_scenario(scenario, samples) for scenario in scenarios]
    console.print(_table(comparisons, tree, reference))
    _print_differences(console, comparisons)
    if json_path is not None:
        write_json(json_path, _report(comparisons, tree, reference))
        console.print(f"numbers written to {json_path}", markup=False)
    return comparisons
