"""``ato run`` on the terminal: a progress bar while the scenario runs, then the KPIs."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from deploy.scenario.kpi_model import Kpis, TrainSummary, WallTimeBreakdown
from deploy.scenario.loader import ScenarioFileError, load_scenario
from deploy.scenario.runner import Progress as RunProgress
from deploy.scenario.runner import RunOptions, RunOutcome, ScenarioRunError, run_scenario

if TYPE_CHECKING:
    from deploy.scenario.campaign import CellResult

__all__ = ["campaign_from_cli", "run_database_url", "run_from_cli", "summary_table"]


def run_from_cli(
    scenario: str,
    *,
    fast: bool,
    speed: float,
    seed: int | None,
    report: Path | None,
    insecure: bool = False,
    database_url: str | None = None,
) -> int:
    """Run and print; the exit status: 0 passed, 1 an expectation failed, 2 could not run.
    A stored line is read from ``database_url`` (default :func:`run_database_url`)."""
    console = Console(stderr=True)
    try:
        spec = load_scenario(scenario)
    except ScenarioFileError as exc:
        console.print(f"[red]{exc}[/red]")
        return 2
    options = RunOptions(
        fast=fast,
        speed=speed,
        seed=seed,
        report_dir=report,
        insecure=insecure,
        database_url=database_url or run_database_url(),
    )
    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TextColumn("{task.fields[sim]}"),
        TimeElapsedColumn(),
    )
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task(spec.name, total=spec.duration_s, sim="")

        def show(frame: RunProgress) -> None:
            text = (
                f"t={frame.sim_time_s:7.1f} s  v={frame.speed_kmh:5.1f} km/h  ETCS "
                f"{frame.etcs_mode}  ATO {frame.ato_state}  SC {frame.sc_state}"
            )
            bar.update(task, completed=frame.sim_time_s, sim=text)

        try:
            outcome = run_scenario(spec, options, progress=show)
        except ScenarioRunError as exc:
            console.print(f"[red]cannot run {spec.name}: {exc}[/red]")
            return 2
    Console().print(summary_table(outcome))
    if report is not None:
        written = "kpis.json, telemetry.npz, report.html" if outcome.columns else "kpis.json"
        console.print(f"report written to {report}/ ({written})")
    return 0 if outcome.passed else 1


def run_database_url() -> str:
    """Where ``ato run`` reads a stored line that is not built in: the database the trackside
    uses, ``ATO_DATABASE_URL``, else the trackside's default."""
    from trackside.config import Settings

    default: str = Settings.model_fields["database_url"].default
    return os.environ.get("ATO_DATABASE_URL", default)


def _format(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.3f}"
    if isinstance(value, BaseModel):
        return ", ".join(f"{k} {_format(v)}" for k, v in value.model_dump().items())
    return str(value)


def _breakdown_text(breakdown: WallTimeBreakdown, shown: int = 5) -> str:
    """The stepping's wall time and its largest tasks, e.g. ``lockstep 70.1 s: sfa 26 %, …``."""
    tasks = [
        f"{name} {100 * item.share:.0f} %"
        for name, item in list(breakdown.tasks.items())[:shown]
        if item.share is not None
    ]
    text = f"lockstep {breakdown.lockstep_s:.1f} s: " + ", ".join(tasks)
    if breakdown.outside_lockstep_s is not None:
        text += f"; outside it {breakdown.outside_lockstep_s:.1f} s"
    return text


def _headline(kpis: Kpis) -> list[tuple[str, object]]:
    """The KPIs the table shows first, by name (``vc_outcome`` for ``[vc]`` runs only)."""
    rows: list[tuple[str, object]] = [
        ("seed", kpis.seed),
        ("sim_time_s", kpis.sim_time_s),
        ("wall_time_s", kpis.wall_time_s),
        ("real_time_factor", kpis.real_time_factor),
        ("max_overspeed_kmh", kpis.max_overspeed_kmh),
        ("etcs_sb_count", kpis.etcs_sb_count),
        ("etcs_eb_count", kpis.etcs_eb_count),
        ("vc_eb_count", kpis.vc_eb_count),
        ("system_decay", kpis.system_decay),
        ("traction_energy_kwh", kpis.traction_energy_kwh),
        ("ad_speed_rms_kmh", kpis.ad_speed_rms_kmh),
        ("position_error_m", kpis.position_error_m),
        ("nmpc_ms", kpis.nmpc_ms),
    ]
    if kpis.vc_outcome is not None:
        rows.append(("vc_outcome", kpis.vc_outcome))
    return rows


def _fleet_train_text(train: TrainSummary) -> str:
    """One train of a multi-train run, in a line."""
    delay = train.max_arrival_delay_s
    return (
        f"{'passed' if train.passed else 'FAILED'}, {train.stops} stops, "
        f"latest {'-' if delay is None else f'{delay:+.1f}'} s, held {train.held_s:.1f} s "
        f"({train.eoa_stops} EoA stops), ETCS SB/EB {train.etcs_sb_count}/"
        f"{train.etcs_eb_count}, VC EB {train.vc_eb_count}"
    )


def summary_table(outcome: RunOutcome) -> Table:
    """The run's headline KPIs and each expectation."""
    kpis = outcome.kpis
    table = Table(title=f"{kpis.scenario}: {'PASSED' if outcome.passed else 'FAILED'}")
    table.add_column("KPI / expectation")
    table.add_column("value")
    for name, value in _headline(kpis):
        table.add_row(name, _format(value))
    if kpis.wall_time_breakdown is not None:
        table.add_row("wall time by task", _breakdown_text(kpis.wall_time_breakdown))
    for stop in kpis.stops:
        table.add_row(
            f"stop {stop.name}",
            f"arrival {stop.arrival_error_s:+.2f} s, position {stop.stop_error_m:+.3f} m",
        )
    if kpis.fleet is not None:
        for train in kpis.fleet.trains:
            table.add_row(f"train {train.vehicle_id}", _fleet_train_text(train))
        fleet = kpis.fleet
        table.add_row(
            "least distance between trains",
            f"{_format(fleet.min_distance_m)} m at {_format(fleet.min_distance_at_s)} s "
            f"({' behind '.join(fleet.min_distance_between) or 'none'})",
        )
        for headway in fleet.headways:
            table.add_row(
                f"headway at {headway.stop}",
                f"{headway.headway_s:.1f} s ({headway.behind} after {headway.ahead})",
            )
    for item in kpis.vc_interventions:
        timing = (
            f"hazard→command {item.hazard_to_eb_command_ms} ms, "
            f"hazard→full EB {item.total_to_full_eb_ms} ms"
        )
        table.add_row(f"VC EB ({item.cause})", timing)
    for result in kpis.expectations:
        mark = "[green]ok[/green]" if result.ok else "[red]FAIL[/red]"
        table.add_row(f"{mark} {result.name}", result.detail)
    return table


@contextlib.contextmanager
def _campaign_progress(
    console: Console, total: int
) -> Iterator[tuple[Progress, Callable[[CellResult], None]]]:
    """A campaign's progress bar, and the callback that prints one line a run as it ends, so
    that a long campaign can be followed in a log."""
    with Progress(
        TextColumn("[bold]campaign"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        console=console,
    ) as bar:
        task = bar.add_task("campaign", total=total)
        done = [0]

        def finished(result: CellResult) -> None:
            done[0] += 1
            bar.console.print(
                f"[{done[0]}/{total}] {_result_line(result)}",
                markup=False,
                highlight=False,
                soft_wrap=True,
            )
            bar.advance(task)

        yield bar, finished


def campaign_from_cli(
    scenarios: list[str],
    *,
    seeds: int,
    first_seed: int,
    workers: int,
    vary: list[str],
    json_path: Path | None,
    cluster: str | None = None,
) -> int:
    """Run the matrix (on the Dask cluster at ``cluster`` if given, else over ``workers`` local
    processes) and print the summary, written to ``json_path`` as the runs end; 0 unless a run
    crashed or ended unsafe, 2 if the matrix or the cluster cannot be used."""
    from deploy.scenario.campaign import (
        FAULT_SCENARIOS,
        PartialSummary,
        apply_setting,
        matrix,
        parse_variation,
        summarise,
    )
    from deploy.scenario.cluster import ClusterError, run_cells

    console = Console(stderr=True)
    try:
        variations = [parse_variation(text) for text in vary]
        names = scenarios or list(FAULT_SCENARIOS)
        cells = matrix(names, range(first_seed, first_seed + seeds), variations)
        for cell in {(cell.scenario, cell.setting): cell for cell in cells}.values():
            apply_setting(load_scenario(cell.scenario), cell.setting)
    except (ValueError, ScenarioFileError) as exc:
        console.print(f"[red]{exc}[/red]")
        return 2
    partial = None if json_path is None else PartialSummary(cells, json_path)
    try:
        with _campaign_progress(console, len(cells)) as (_bar, finished):

            def ended(result: CellResult) -> None:
                finished(result)
                if partial is not None:
                    partial.add(result)

            results, report = run_cells(cells, workers=workers, cluster=cluster, on_result=ended)
    except ClusterError as exc:
        console.print(str(exc), style="red", markup=False, highlight=False)
        return 2
    summary = summarise(results)
    if report is not None:
        summary["cluster"] = report.as_json()
        console.print(
            f"cluster {report.address}: {report.workers} workers, {report.retries} runs retried"
        )
    _print_campaign(summary, results)
    if partial is not None:
        partial.write(**({} if report is None else {"cluster": report.as_json()}))
        console.print(f"summary written to {json_path}")
    return 0 if summary["crashed"] == 0 and summary["unsafe"] == 0 else 1


def _print_campaign(summary: dict[str, Any], results: list[CellResult]) -> None:
    """The table, then each run that crashed, ended unsafe or failed an expectation."""
    Console().print(_campaign_table(summary, results))
    for cell in summary["cells"]:
        if cell["error"] or cell["unsafe"] or cell["failed_expectations"]:
            what = cell["error"] or "; ".join(cell["unsafe"] + cell["failed_expectations"])
            Console().print(f"  {cell['label']}: {what.strip().splitlines()[-1]}")


def _campaign_table(summary: dict[str, Any], results: list[CellResult]) -> Table:
    """One row a scenario: its runs' verdicts, margins, stop errors and speed."""
    table = Table(
        title=f"campaign: {summary['runs']} runs, {summary['crashed']} crashed, "
        f"{summary['unsafe']} unsafe"
    )
    for column in (
        "scenario",
        "runs",
        "passed",
        "failed",
        "crashed",
        "unsafe",
        "max overspeed [km/h]",
        "min EoA margin [m]",
        "|stop error| [m]",
        "RTF median",
    ):
        table.add_column(column)
    for name, row in summary["scenarios"].items():
        kpis = row["kpis"]

        def stat(key: str, which: str, kpis: dict[str, Any] = kpis) -> str:
            value = kpis.get(key)
            return "—" if value is None else f"{value[which]:.2f}"

        table.add_row(
            name,
            str(row["runs"]),
            str(row["passed"]),
            str(row["failed"]),
            str(row["crashed"]),
            str(row["unsafe"]),
            stat("max_overspeed_kmh", "max"),
            _min_margin(results, name),
            " / ".join(stat("stops.stop_error_m.abs", which) for which in ("median", "p99", "max")),
            stat("real_time_factor", "median"),
        )
    return table


def _result_line(result: CellResult) -> str:
    """``obstacle seed=3: passed (RTF 14.2)``, or what went wrong."""
    label, kpis = result.cell.label, result.kpis
    if kpis is None:
        last = (result.error or "").strip().splitlines() or ["no error text"]
        return f"{label}: CRASHED ({last[-1]})"
    if result.unsafe:
        return f"{label}: UNSAFE ({'; '.join(result.unsafe)})"
    failed = [item.name for item in kpis.expectations if not item.ok]
    verdict = "passed" if not failed else "failed: " + "; ".join(failed)
    return f"{label}: {verdict} (RTF {kpis.real_time_factor:.1f})"


def _min_margin(results: list[CellResult], name: str) -> str:
    margins = [
        margin
        for r in results
        if r.cell.scenario == name
        and r.kpis is not None
        and (margin := r.kpis.min_eoa_margin_m) is not None
    ]
    return f"{min(margins):.2f}" if margins else "—"


def generated_campaign_from_cli(
    count: int,
    *,
    seed: int,
    space_path: Path | None,
    out_dir: Path | None,
    workers: int,
    shrink_runs: int,
    json_path: Path | None,
    resume: bool = False,
    cluster: str | None = None,
) -> int:
    """Generate, run (on the Dask cluster at ``cluster`` if given), judge, shrink and print; 0
    when no invariant is violated, 1 otherwise, 2 when the space or the cluster cannot be used.
    Each run's result is kept in the output directory as it ends (``--resume``)."""
    from deploy.scenario.cluster import ClusterError
    from deploy.scenario.generate import default_out_dir
    from deploy.scenario.generated import run_generated, summarise_generated
    from deploy.scenario.space import SpaceFileError, load_space

    console = Console(stderr=True)
    try:
        space = load_space(space_path)
    except SpaceFileError as exc:
        console.print(f"[red]{exc}[/red]", markup=False, highlight=False)
        return 2
    out = out_dir or default_out_dir(seed)
    console.print(f"generating {count} scenarios (space {space.name}, seed {seed}) into {out}/")
    try:
        with _campaign_progress(console, count) as (bar, finished):
            campaign = run_generated(
                space,
                count=count,
                seed=seed,
                out_dir=out,
                workers=workers,
                shrink_runs=shrink_runs,
                on_result=finished,
                on_shrink=lambda text: bar.console.print(text, markup=False, highlight=False),
                resume=resume,
                cluster=cluster,
                summary_path=json_path,
            )
    except ClusterError as exc:
        console.print(
            f"{exc} (the runs ended are kept: --resume)", style="red", markup=False, highlight=False
        )
        return 2
    summary = summarise_generated(campaign, seed=seed, space=space.name)
    _print_generated(summary)
    if json_path is not None:
        from deploy.scenario.campaign import write_summary

        write_summary(summary, json_path)
        console.print(f"summary written to {json_path}")
    return 0 if summary["violations"] == 0 else 1


def _print_generated(summary: dict[str, Any]) -> None:
    out = Console()
    failures = Table(
        title=f"generated: {summary['runs']} runs, {summary['violations']} with an "
        "invariant violated"
    )
    for column in ("invariant", "runs violating", "first", "shrunk (runs: steps)"):
        failures.add_column(column)
    for name, entry in summary["invariants"].items():
        shrunk = entry["shrunk"]
        text = (
            "—"
            if shrunk is None
            else (
                f"{shrunk['file']} ({shrunk['runs']}: {'; '.join(shrunk['steps']) or 'none kept'})"
            )
        )
        failures.add_row(name, str(entry["count"]), Path(entry["first"]).stem, text)
    out.print(failures)
    kpis = Table(title="KPI distributions (over every stop, or every run)")
    for column in ("KPI", "median", "p99", "max"):
        kpis.add_column(column)
    for key, stats in summary["distributions"].items():
        cells = (
            ["—"] * 3 if stats is None else [f"{stats[k]:.3f}" for k in ("median", "p99", "max")]
        )
        kpis.add_row(key, *cells)
    out.print(kpis)
    for cell in summary["cells"]:
        for violation in cell["violations"]:
            out.print(
                f"  {Path(cell['scenario']).stem}: {violation['invariant']}: {violation['detail']}",
                markup=False,
                highlight=False,
            )
