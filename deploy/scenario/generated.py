"""``ato campaign --generate N --seed S``: generate, run, judge the invariants, shrink failures.

The N scenarios of seed S are drawn from the space (``deploy.scenario.space``) and written as
scenario files (``gen-<S>-<index>.toml``); each runs as a cell of the campaign
(``deploy.scenario.campaign``) with its own run seed, and its KPIs are judged by the invariants
(``deploy.scenario.invariants``). For the first failing scenario of each invariant the shrinker
(``deploy.scenario.shrink``) looks for a simpler one that fails the same way, and writes it
beside the others as ``<name>-shrunk.toml``. The summary adds, to the campaign's, the failures
by invariant and the distributions of the stop error, the arrival error, the NMPC's p99 and
max solve time and the traction energy over every run.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from deploy.scenario.campaign import (
    Cell,
    CellResult,
    PartialSummary,
    distribution,
    run_campaign,
    summarise,
)
from deploy.scenario.cluster import ClusterReport, run_cells
from deploy.scenario.generate import Draw, draw, write_scenario
from deploy.scenario.invariants import INVARIANTS, Violation, judge
from deploy.scenario.kpi_model import Kpis, ServedStop
from deploy.scenario.loader import load_scenario
from deploy.scenario.run_store import RunStore, code_fingerprint
from deploy.scenario.schema import InvariantName, ScenarioSpec
from deploy.scenario.shrink import ShrinkResult, shrink
from deploy.scenario.space import GeneratorSpace
from deploy.scenario.toml_out import scenario_toml

__all__ = ["GeneratedCampaign", "kpi_distributions", "run_generated", "summarise_generated"]

STOP_DISTRIBUTIONS: dict[str, Callable[[ServedStop], float]] = {
    "stop_error_m.abs": lambda stop: abs(stop.stop_error_m),
    "arrival_error_s.abs": lambda stop: abs(stop.arrival_error_s),
}
"""The KPI distributions of the summary over every stop of every run."""
RUN_DISTRIBUTIONS: dict[str, Callable[[Kpis], float | None]] = {
    "nmpc_ms.p99": lambda kpis: None if kpis.nmpc_ms is None else kpis.nmpc_ms.p99,
    "nmpc_ms.max": lambda kpis: None if kpis.nmpc_ms is None else kpis.nmpc_ms.max,
    "traction_energy_kwh": lambda kpis: kpis.traction_energy_kwh,
}
"""The KPI distributions of the summary over every run."""
DISTRIBUTIONS = (*STOP_DISTRIBUTIONS, *RUN_DISTRIBUTIONS)
"""The summary's KPI distributions, by their names in it."""


@dataclass(frozen=True)
class GeneratedCampaign:
    results: list[CellResult]
    specs: dict[str, ScenarioSpec]
    """By file path (the cells' scenario)."""
    violations: dict[str, list[Violation]]
    """By file path."""
    shrunk: dict[InvariantName, tuple[Path, ShrinkResult]]
    cluster: ClusterReport | None = None
    """What the cluster retried (a campaign run with ``cluster``)."""


def _judged(spec: ScenarioSpec, result: CellResult) -> list[Violation]:
    return judge(spec, result.kpis, error=result.error)


def run_spec_in_worker(spec: ScenarioSpec, directory: Path) -> CellResult:
    """One run of ``spec`` in a spawned worker process (as a campaign's cell), via its file."""
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{spec.name}.toml"
    path.write_text(scenario_toml(spec), encoding="utf-8")
    return run_campaign([Cell(str(path), spec.seed)], workers=1)[0]


def run_generated(
    space: GeneratorSpace,
    *,
    count: int,
    seed: int,
    out_dir: Path,
    workers: int,
    shrink_runs: int = 12,
    on_result: Callable[[CellResult], None] | None = None,
    on_shrink: Callable[[str], None] | None = None,
    resume: bool = False,
    cluster: str | None = None,
    summary_path: Path | None = None,
) -> GeneratedCampaign:
    """Generate, run, judge and shrink; every file is written under ``out_dir``, each run's
    result too as it ends (``out_dir/results``); with ``resume``, the runs whose kept result
    matches their scenario, seed and code are not made again (:mod:`deploy.scenario.run_store`).
    With ``cluster`` (a Dask scheduler's address) the runs are made on it; the shrinker's few
    runs stay local. With ``summary_path`` the campaign's summary of the runs ended so far is
    written there as they end (:class:`deploy.scenario.campaign.PartialSummary`)."""
    drawn: dict[str, Draw] = {}
    specs: dict[str, ScenarioSpec] = {}
    for index in range(count):
        item = draw(space, seed, index)
        path = str(write_scenario(space, item, out_dir))
        drawn[path], specs[path] = item, load_scenario(path)
    cells = [Cell(path, spec.seed) for path, spec in specs.items()]
    results, report = _run_kept(
        cells,
        RunStore(out_dir / "results", code_fingerprint()),
        workers=workers,
        resume=resume,
        on_result=on_result,
        cluster=cluster,
        partial=None if summary_path is None else PartialSummary(cells, summary_path),
    )
    violations = {r.cell.scenario: _judged(specs[r.cell.scenario], r) for r in results}
    shrunk: dict[InvariantName, tuple[Path, ShrinkResult]] = {}
    for invariant in INVARIANTS:
        failing = [
            path for path in specs if any(v.invariant == invariant for v in violations[path])
        ]
        first = failing[0] if failing else None
        if first is None or shrink_runs <= 0:
            continue
        if on_shrink is not None:
            on_shrink(f"shrinking {Path(first).stem} ({invariant})")

        def run(spec: ScenarioSpec) -> list[Violation]:
            return _judged(spec, run_spec_in_worker(spec, out_dir / "shrink"))

        result = shrink(
            space, drawn[first], invariant, run, max_runs=shrink_runs, violations=violations[first]
        )
        target = write_scenario(space, result.draw, out_dir)
        shrunk[invariant] = (target, result)
    return GeneratedCampaign(results, specs, violations, shrunk, report)


def _run_kept(
    cells: Sequence[Cell],
    store: RunStore,
    *,
    workers: int,
    resume: bool,
    on_result: Callable[[CellResult], None] | None,
    cluster: str | None = None,
    partial: PartialSummary | None = None,
) -> tuple[list[CellResult], ClusterReport | None]:
    """The cells' results in their order: kept ones taken back (with ``resume``), the others
    run (on ``cluster`` if given), each kept as it ends."""
    kept = {cell: store.load(cell) for cell in cells} if resume else {}

    def ended(result: CellResult) -> None:
        if partial is not None:
            partial.add(result)
        if on_result is not None:
            on_result(result)

    for result in kept.values():
        if result is not None:
            ended(result)

    def finished(result: CellResult) -> None:
        store.save(result)
        ended(result)

    missing = [cell for cell in cells if kept.get(cell) is None]
    ran, report = run_cells(missing, workers=workers, cluster=cluster, on_result=finished)
    made = iter(ran)
    return [kept.get(cell) or next(made) for cell in cells], report


def _values(results: Sequence[CellResult], key: str) -> list[float]:
    ran = [r.kpis for r in results if r.kpis is not None]
    if key in STOP_DISTRIBUTIONS:
        of_stop = STOP_DISTRIBUTIONS[key]
        return [of_stop(stop) for kpis in ran for stop in kpis.stops]
    of_run = RUN_DISTRIBUTIONS[key]
    return [value for kpis in ran if (value := of_run(kpis)) is not None]


def kpi_distributions(results: Sequence[CellResult]) -> dict[str, dict[str, float] | None]:
    """Median, p99 and max of each of :data:`DISTRIBUTIONS` over the runs."""
    return {key: distribution(_values(results, key)) for key in DISTRIBUTIONS}


def summarise_generated(campaign: GeneratedCampaign, *, seed: int, space: str) -> dict[str, Any]:
    """The campaign's summary with the invariants: failures by invariant, each with its first
    failing scenario and its shrunk file; the KPI distributions; each cell's violations."""
    summary = summarise(campaign.results)
    by_invariant: dict[str, Any] = {}
    for invariant in INVARIANTS:
        failing = [
            path
            for path, found in campaign.violations.items()
            if any(v.invariant == invariant for v in found)
        ]
        if not failing:
            continue
        entry: dict[str, Any] = {
            "count": len(failing),
            "scenarios": failing,
            "first": failing[0],
            "shrunk": None,
        }
        if invariant in campaign.shrunk:
            path, result = campaign.shrunk[invariant]
            entry["shrunk"] = {"file": str(path), "runs": result.runs, "steps": list(result.steps)}
        by_invariant[invariant] = entry
    summary.update(
        generated={"seed": seed, "space": space, "count": len(campaign.specs)},
        pending=0,
        violations=sum(1 for found in campaign.violations.values() if found),
        invariants=by_invariant,
        distributions=kpi_distributions(campaign.results),
    )
    if campaign.cluster is not None:
        summary["cluster"] = campaign.cluster.as_json()
    for cell in summary["cells"]:
        cell["violations"] = [
            {"invariant": v.invariant, "detail": v.detail}
            for v in campaign.violations.get(cell["scenario"], [])
        ]
    return summary
