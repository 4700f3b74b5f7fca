"""``ato``: the one command (CONTRACT.md §1)."""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from deploy.cli_pki import pki_app
from deploy.cli_sfa import sfa_app
from deploy.cli_trackdb import trackdb_app
from protocol import DEFAULT_ROUTER_ENDPOINT, TlsFiles, ZenohSettings
from protocol.router import run_router

__all__ = ["app"]

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from deploy.processes import MetricsEndpoint

app = typer.Typer(
    help="ato: an open GoA4 ATO over ETCS stack for an unmanned inspection vehicle.",
    no_args_is_help=True,
    add_completion=False,
)
bench_app = typer.Typer(help="Benchmarks that print numbers.", no_args_is_help=True)
app.add_typer(bench_app, name="bench")
app.add_typer(trackdb_app, name="trackdb")
vc_app = typer.Typer(help="Vital Control tools.", no_args_is_help=True)
app.add_typer(vc_app, name="vc")
app.add_typer(sfa_app, name="sfa")
app.add_typer(pki_app, name="pki")
audit_app = typer.Typer(help="The trackside's audit log.", no_args_is_help=True)
app.add_typer(audit_app, name="audit")

ZenohOption = Annotated[str, typer.Option("--zenoh", help="Zenoh router endpoint to connect to.")]
PkiOption = Annotated[
    Path | None,
    typer.Option(
        "--pki",
        help="The deployment's PKI directory (ato pki): TLS with mutual authentication, with "
        "this party's certificate. Without it the links are plain TCP: insecure, for debugging.",
    ),
]
TrackDirOption = Annotated[
    Path | None,
    typer.Option(
        "--track-dir",
        help="Where the track data received from the trackside are kept, verified. "
        "Default: .ato/track/VEHICLE.",
    ),
]

VcReplicasOption = Annotated[
    int,
    typer.Option(
        "--vc-replicas",
        min=1,
        max=2,
        help="VC boards: 2 in 2-out-of-2 with voter and watchdog (the vehicle's), 1 alone.",
    ),
]
MetricsPortOption = Annotated[
    int | None,
    typer.Option(
        "--metrics-port",
        min=0,
        help="Serve Prometheus metrics on this port (0: a free one, logged); off by default.",
    ),
]
MetricsAddrOption = Annotated[
    str,
    typer.Option(
        "--metrics-addr",
        help="The metrics' address: loopback by default; another one needs --pki (HTTPS, "
        "client certificates of the deployment's CA).",
    ),
]


def _warn_insecure(part: str, pki: Path | None) -> None:
    from rich.console import Console

    if pki is None:
        Console(stderr=True).print(
            f"[bold red]INSECURE: {part}: plain TCP links, no authentication, no access "
            "control; anyone who reaches the endpoint can command the trains. Debugging only."
            "[/bold red]"
        )


DatabaseOption = Annotated[
    str | None,
    typer.Option(
        "--database", help="SQLAlchemy URL (default: ATO_DATABASE_URL, else sqlite:///ato.db)."
    ),
]


def _logging(verbose: bool) -> None:
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.INFO,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    if not verbose:  # httpx logs each request of the demo's driver and of ``ato up``'s checks
        for chatty in ("alembic", "httpx"):
            logging.getLogger(chatty).setLevel(logging.WARNING)


@app.command()
def router(
    listen: Annotated[
        list[str] | None, typer.Option("--listen", help="Endpoint to listen on (repeatable).")
    ] = None,
    connect: Annotated[
        list[str] | None, typer.Option("--connect", help="Another router to join (repeatable).")
    ] = None,
    pki: PkiOption = None,
    name: Annotated[str, typer.Option("--name", help="Its certificate's name.")] = "router",
    vehicle: Annotated[
        list[str] | None, typer.Option("--vehicle", help="A vehicle it admits (repeatable).")
    ] = None,
    trackside: Annotated[
        list[str] | None,
        typer.Option("--trackside", help="A trackside instance it admits (repeatable)."),
    ] = None,
    peer_router: Annotated[
        list[str] | None,
        typer.Option("--peer-router", help="Another router's certificate name (repeatable)."),
    ] = None,
    verbose: bool = False,
) -> None:
    """Run a Zenoh router (default tcp/127.0.0.1:7447; with --pki, TLS and access control)."""
    from deploy.processes import stop_on_signals
    from protocol.access import access_control

    _logging(verbose)
    _warn_insecure("ato router", pki)
    tls = None if pki is None else TlsFiles.of(pki, name)
    rules = None
    if pki is not None:
        rules = access_control(
            vehicles=vehicle or [], tracksides=trackside or ["ts1"], routers=peer_router or []
        )
    stop = threading.Event()
    with stop_on_signals(stop):
        run_router(
            stop,
            listen=listen or [DEFAULT_ROUTER_ENDPOINT],
            connect=connect or [],
            tls=tls,
            access_control=rules,
        )


@app.command()
def trackside(
    host: str = "127.0.0.1",
    port: int = 8000,
    zenoh: ZenohOption = DEFAULT_ROUTER_ENDPOINT,
    database: Annotated[
        str | None, typer.Option("--database", help="SQLAlchemy URL (default: ATO_DATABASE_URL)")
    ] = None,
    pki: PkiOption = None,
    verbose: bool = False,
) -> None:
    """Run the ATO-TS web service."""
    from trackside.config import Settings
    from trackside.main import main

    _logging(verbose)
    _warn_insecure("ato trackside", pki)
    overrides: dict[str, object] = {"zenoh_connect": (zenoh,), "zenoh_pki_dir": pki}
    if database is not None:
        overrides["database_url"] = database
    main(Settings(**overrides), host=host, port=port)  # type: ignore[arg-type]


def _metrics_endpoint(port: int, addr: str, tls: TlsFiles | None) -> MetricsEndpoint:
    """An onboard's metrics endpoint: plain HTTP on the loopback interface, HTTPS with client
    certificates elsewhere (which needs the PKI)."""
    from deploy.processes import MetricsEndpoint

    loopback = addr in ("127.0.0.1", "::1", "localhost")
    if not loopback and tls is None:
        raise typer.BadParameter("metrics off the loopback interface need --pki")
    return MetricsEndpoint(port, addr, None if loopback else tls)


@app.command()
def onboard(
    vehicle: Annotated[str, typer.Option("--vehicle", help="Vehicle id, e.g. URV1.")],
    zenoh: ZenohOption = DEFAULT_ROUTER_ENDPOINT,
    line: Annotated[
        str, typer.Option("--line", help="Line id: any line the trackside holds.")
    ] = "bologna-ring",
    speed: Annotated[float, typer.Option("--speed", help="Simulated s per wall s.")] = 1.0,
    fidelity: Annotated[
        str, typer.Option("--fidelity", help="Plant: point_mass or bogie (VCU + 10-DOF bogie).")
    ] = "point_mass",
    vc_replicas: VcReplicasOption = 2,
    vc_datalog: Annotated[
        Path | None,
        typer.Option(
            "--vc-datalog",
            help="The VC's datalog (JSON Lines; `ato vc replay` reads "
            "it). Default: .ato/vc/VEHICLE.jsonl.",
        ),
    ] = None,
    no_vc_datalog: Annotated[
        bool, typer.Option("--no-vc-datalog", help="Do not record the VC's datalog.")
    ] = False,
    track_dir: TrackDirOption = None,
    pki: PkiOption = None,
    metrics_port: MetricsPortOption = None,
    metrics_addr: MetricsAddrOption = "127.0.0.1",
    verbose: bool = False,
) -> None:
    """Run one ATO-OB process on a line the trackside holds (fetched if there is no copy)."""
    from deploy.processes import run_onboard, stop_on_signals

    _logging(verbose)
    _warn_insecure("ato onboard", pki)
    tls = None if pki is None else TlsFiles.of(pki, vehicle)
    if speed <= 0:
        raise typer.BadParameter("--speed must be positive")
    if fidelity not in ("point_mass", "bogie"):
        raise typer.BadParameter("--fidelity must be point_mass or bogie")
    datalog = vc_datalog or Path(".ato/vc") / f"{vehicle}.jsonl"
    metrics = None
    if metrics_port is not None:
        metrics = _metrics_endpoint(metrics_port, metrics_addr, tls)
    stop = threading.Event()
    with stop_on_signals(stop):
        run_onboard(
            vehicle,
            zenoh=ZenohSettings(connect=(zenoh,), tls=tls),
            line_id=line,
            speed_factor=speed,
            stop=stop,
            fidelity=fidelity,  # type: ignore[arg-type]
            vc_replicas=vc_replicas,
            vc_datalog=None if no_vc_datalog else datalog,
            track_dir=track_dir or Path(".ato/track") / vehicle,
            metrics=metrics,
        )


@app.command()
def up(
    vehicles: Annotated[int, typer.Option("--vehicles", min=1, max=100)] = 1,
    line: Annotated[
        str, typer.Option("--line", help="Line id: built in, or imported into the database.")
    ] = "bologna-ring",
    port: Annotated[int, typer.Option(help="Trackside HTTP port (0: a free one).")] = 8000,
    router_port: Annotated[int, typer.Option(help="Router TCP port (0: a free one).")] = 7447,
    speed: Annotated[float, typer.Option(help="Simulated s per wall s.")] = 1.0,
    data_dir: Annotated[Path, typer.Option(help="Logs, database, admin password.")] = Path(
        ".ato/up"
    ),
    database: DatabaseOption = None,
    simulated_operators: Annotated[
        bool, typer.Option(help="The simulated operator answers every vehicle's VC requests.")
    ] = False,
    insecure: Annotated[
        bool,
        typer.Option(
            "--insecure",
            help="Plain TCP links, no certificates, no access control: debugging only.",
        ),
    ] = False,
) -> None:
    """Router, trackside and N onboard processes, each its own process, until Ctrl-C.

    The Zenoh links are TLS with mutual authentication and the router's access control, with
    certificates of a CA kept in DATA_DIR/pki (made on the first start)."""
    from deploy.processes import stop_on_signals
    from deploy.up import UpPlan, run_up

    stop = threading.Event()
    plan = UpPlan(
        vehicles=vehicles,
        line=line,
        port=port,
        router_port=router_port,
        data_dir=data_dir,
        database=database,
        speed=speed,
        simulated_operators=simulated_operators,
        insecure=insecure,
    )
    with stop_on_signals(stop):
        code = run_up(plan, stop, out=lambda text: print(text, flush=True))
    raise typer.Exit(code)


@app.command()
def demo(
    port: int = 8000,
    data_dir: Annotated[Path, typer.Option(help="Where the demo keeps its database.")] = Path(
        ".ato"
    ),
    line: Annotated[
        str,
        typer.Option(
            "--line", help="Line id: a built-in line or one imported into the demo's database."
        ),
    ] = "bologna-ring",
    verbose: bool = False,
) -> None:
    """Router, trackside and URV1 on bologna-ring (or --line), with the console on
    http://127.0.0.1:PORT/."""
    from deploy.demo import run_demo

    _logging(verbose)
    run_demo(port=port, data_dir=data_dir, line_id=line)


@app.command()
def scenarios(
    kpis_schema: Annotated[
        bool,
        typer.Option(
            "--kpis-schema",
            help="Print the JSON Schema of kpis.json (as in deploy/scenario/kpis.schema.json).",
        ),
    ] = False,
) -> None:
    """List the scenario library's names, one a line."""
    if kpis_schema:
        from deploy.scenario.kpi_model import kpis_json_schema

        typer.echo(kpis_json_schema(), nl=False)
        return
    from deploy.scenario import scenario_names

    for name in scenario_names():
        print(name)


@app.command("run")
def run_scenario(
    scenario: Annotated[str, typer.Argument(help="A scenario name (see `ato scenarios`) or file.")],
    fast: Annotated[bool, typer.Option("--fast", help="Lockstep, as fast as possible.")] = False,
    speed: Annotated[float, typer.Option(help="Real-time pacing factor (without --fast).")] = 1.0,
    seed: Annotated[int | None, typer.Option(help="Override the scenario's seed.")] = None,
    report: Annotated[
        Path | None, typer.Option(help="Write kpis.json, telemetry.npz and report.html here.")
    ] = None,
    insecure: Annotated[
        bool,
        typer.Option("--insecure", help="Plain TCP between trackside and onboard: debugging only."),
    ] = False,
    database: DatabaseOption = None,
) -> None:
    """Run one scenario with trackside, onboard and operator in this process; exit 0 iff every
    expectation holds. The trackside and the onboard talk over TLS with certificates of a CA
    made for the run, the trackside enforcing the access control. A scenario's `line` that is
    not built in is read (only read) from --database."""
    from deploy.scenario.console import run_from_cli

    _warn_insecure("ato run", None if insecure else Path())
    raise typer.Exit(
        run_from_cli(
            scenario,
            fast=fast,
            speed=speed,
            seed=seed,
            report=report,
            insecure=insecure,
            database_url=database,
        )
    )


# The generated campaign's options (``ato campaign --generate``), named so that the command's
# signature reads as its list of options.
GenerateOption = Annotated[
    int | None,
    typer.Option(
        min=1,
        help="Generate this many scenarios from the space and judge the "
        "invariants (instead of named scenarios).",
    ),
]
GeneratorSeedOption = Annotated[int, typer.Option(min=0, help="--generate: the generator's seed.")]
SpaceOption = Annotated[
    Path | None, typer.Option(help="--generate: the space file (default: the ring's).")
]
GeneratedOutOption = Annotated[
    Path | None,
    typer.Option(help="--generate: where the files go (default .ato/generated/seed-S)."),
]
ShrinkRunsOption = Annotated[
    int,
    typer.Option(min=0, help="--generate: runs allowed to shrink each invariant's first failure."),
]
ResumeOption = Annotated[
    bool,
    typer.Option(
        help="--generate: take back the results kept in --out of runs of the same scenario, "
        "seed and code; run only the others."
    ),
]

ClusterOption = Annotated[
    str | None,
    typer.Option(
        "--cluster",
        metavar="ADDRESS",
        help="Run on the Dask cluster of this scheduler (tcp://host:8786, or tls:// with the "
        "certificates of Dask's configuration) instead of --workers local processes; 'local' "
        "starts a Dask cluster of --workers processes for the campaign.",
    ),
]


@app.command()
def campaign(
    scenarios: Annotated[
        list[str] | None, typer.Argument(help="Scenario names (default: the fault scenarios).")
    ] = None,
    seeds: Annotated[int, typer.Option(help="Seeds per scenario.")] = 20,
    first_seed: Annotated[int, typer.Option(help="The first seed.")] = 0,
    workers: Annotated[int, typer.Option(help="Worker processes.")] = 2,
    vary: Annotated[
        list[str] | None, typer.Option(help="KEY=V1,V2: sweep a scenario field (repeatable).")
    ] = None,
    json_path: Annotated[Path | None, typer.Option("--json", help="Write the summary.")] = None,
    generate: GenerateOption = None,
    seed: GeneratorSeedOption = 1,
    space: SpaceOption = None,
    out: GeneratedOutOption = None,
    shrink_runs: ShrinkRunsOption = 12,
    resume: ResumeOption = False,
    cluster: ClusterOption = None,
) -> None:
    """Scenarios × seeds × variations in lockstep over worker processes; a summary table. Exit
    1 if a run crashed or ended unsafe (overspeed beyond the EBI, EoA passed, obstacle reached).
    With --generate N: N scenarios drawn from a space, judged by the invariants, each
    invariant's first failure shrunk; exit 1 on any violation. With --cluster ADDRESS: the runs
    on a Dask cluster (docs/scenarios.md, "Campaigns on a cluster"); exit 2 if it is lost."""
    from deploy.scenario.console import campaign_from_cli, generated_campaign_from_cli

    if generate is not None:
        if scenarios:
            raise typer.BadParameter("--generate draws its scenarios: name none")
        raise typer.Exit(
            generated_campaign_from_cli(
                generate,
                seed=seed,
                space_path=space,
                out_dir=out,
                workers=workers,
                shrink_runs=shrink_runs,
                json_path=json_path,
                resume=resume,
                cluster=cluster,
            )
        )
    raise typer.Exit(
        campaign_from_cli(
            scenarios or [],
            seeds=seeds,
            first_seed=first_seed,
            workers=workers,
            vary=vary or [],
            json_path=json_path,
            cluster=cluster,
        )
    )


AgainstOption = Annotated[
    str | None,
    typer.Option(
        "--against",
        metavar="REF",
        help="Measure side by side with a git ref (a temporary work tree with its own "
        "environment), interleaved run by run with the current tree: both sides' figures and "
        "the ratio tree/ref.",
    ),
]
BenchJsonOption = Annotated[
    Path | None, typer.Option("--json", help="Also write the numbers to this JSON file.")
]


def _bench_failed(exc: Exception) -> typer.Exit:
    from rich.console import Console

    Console(stderr=True).print(f"ato bench: {exc}", markup=False)
    return typer.Exit(code=2)


@bench_app.command("run")
def bench_run(
    scenarios: Annotated[
        list[str] | None,
        typer.Argument(
            help="Scenario names or files (default: bologna-ring and milano-bologna-low-soc)."
        ),
    ] = None,
    runs: Annotated[int, typer.Option(min=1, help="Runs per scenario (and side).")] = 5,
    seed: Annotated[int | None, typer.Option(help="Override the scenarios' seed.")] = None,
    against: AgainstOption = None,
    json_path: BenchJsonOption = None,
) -> None:
    """Whole-stack real-time factor in lockstep: `ato run --fast` again and again, median and
    worst beside the target; with --against REF, side by side with REF and kpis.json compared."""
    from dataclasses import asdict

    from deploy.bench.against import ReferenceTreeError, write_json
    from deploy.bench.run_against import bench_run_against
    from deploy.bench.run_bench import DEFAULT_SCENARIOS
    from deploy.bench.run_bench import bench_run as run

    chosen = scenarios or list(DEFAULT_SCENARIOS)
    if against is None:
        summaries = run(chosen, runs=runs, seed=seed)
        if json_path is not None:
            write_json(json_path, {"scenarios": [asdict(s) for s in summaries]})
        return
    try:
        bench_run_against(against, chosen, runs=runs, seed=seed, json_path=json_path)
    except ReferenceTreeError as exc:
        raise _bench_failed(exc) from exc


@bench_app.command("trackdb")
def bench_trackdb(
    count: Annotated[int, typer.Option(help="Calls per query type.")] = 20000,
) -> None:
    """TrackMap point queries and GPS projection on milano-bologna and bologna-ring."""
    from deploy.bench.trackdb_bench import bench_trackdb as run

    run(count=count)


@bench_app.command("plant")
def bench_plant(
    distance_km: Annotated[float, typer.Option(help="Mission length for the bogie model.")] = 200.0,
    plots: Annotated[
        Path | None,
        typer.Option(help="Also write seed 003 §7 result figures (PNG) into this directory."),
    ] = None,
) -> None:
    """Bogie-model real-time factor over the 200 km mission; point-mass step cost."""
    from deploy.bench.plant_bench import bench_plant as run

    run(distance_km=distance_km, plots_dir=plots)


@bench_app.command("adf")
def bench_adf(
    plots: Annotated[
        Path | None, typer.Option("--plots", help="Write the RD → AD → RD figure here.")
    ] = None,
    against: AgainstOption = None,
    json_path: BenchJsonOption = None,
    runs: Annotated[int, typer.Option(min=1, help="--against: laps per side.")] = 3,
    solver: Annotated[
        str, typer.Option(help="--against: the NMPC's solver (sqpmethod: ours; ipopt).")
    ] = "sqpmethod",
    duration_s: Annotated[
        float | None,
        typer.Option("--duration", min=1.0, help="--against: cut the lap to this many seconds."),
    ] = None,
    energy_legs: Annotated[
        int, typer.Option(min=0, help="Generated legs in the energy-plan table (issue 22).")
    ] = 100,
) -> None:
    """Plan energies, the RD → AD → RD hand-over, NMPC solve times (ours against IPOPT); with
    --against REF, the NMPC's solve times and trajectory on the lap side by side with REF."""
    from deploy.bench.against import ReferenceTreeError, write_json

    if solver not in ("sqpmethod", "ipopt"):
        raise typer.BadParameter("sqpmethod or ipopt", param_hint="--solver")
    if against is None:
        from deploy.bench.adf_bench import bench_adf as run

        results = run(plots_dir=plots, energy_legs=energy_legs)
        if json_path is not None:
            write_json(json_path, {"laps": results})
        return
    from deploy.bench.adf_against import bench_adf_against

    try:
        bench_adf_against(
            against, runs=runs, solver=solver, duration_s=duration_s, json_path=json_path
        )
    except ReferenceTreeError as exc:
        raise _bench_failed(exc) from exc


@bench_app.command("vc")
def bench_vc(
    seconds: Annotated[float, typer.Option(help="Each real-time run's length [s].")] = 60.0,
    runs: Annotated[int, typer.Option(help="Task B runs timed in lockstep (0: none).")] = 1_000_000,
    spin_us: Annotated[
        list[float] | None,
        typer.Option(
            "--spin-us",
            help="Poll the clock for the last µs before each release "
            "(repeatable; default 0 and 500: both, side by side).",
        ),
    ] = None,
) -> None:
    """VC tasks A/B/C: execution time over 10⁶ runs, lateness at 2 ms in real time, misses."""
    from deploy.bench.vc_bench import bench_vc as run

    if seconds <= 0 or runs < 0:
        raise typer.BadParameter("--seconds must be positive and --runs not negative")
    spins = tuple(spin_us) if spin_us else (0.0, 500.0)
    if any(not 0 <= spin < 1e6 for spin in spins):
        raise typer.BadParameter("--spin-us must be in [0, 1e6)")
    run(seconds=seconds, execution_runs=runs, spins_us=spins)


@bench_app.command("sfa")
def bench_sfa(
    ring_s: Annotated[float, typer.Option(help="bologna-ring drive [s].")] = 900.0,
    milano_s: Annotated[float, typer.Option(help="milano-bologna drive [s].")] = 2700.0,
    fuzz: Annotated[int, typer.Option(help="Fuzz datagrams.")] = 100_000,
) -> None:
    """Sensor fusion: accuracy on both lines, fuzzing, IMU cost and UDP throughput."""
    from deploy.bench.sfa_bench import bench_sfa as run

    if ring_s < 130 or milano_s < 130 or fuzz < 1:
        raise typer.BadParameter("drives must last ≥ 130 s and --fuzz be positive")
    run(ring_s=ring_s, milano_s=milano_s, fuzz_count=fuzz)


@vc_app.command("replay")
def vc_replay(
    file: Annotated[Path, typer.Argument(help="A VC datalog (JSON Lines).")],
    kind: Annotated[
        list[str] | None, typer.Option("--kind", help="Only records of this kind (repeatable).")
    ] = None,
) -> None:
    """Print a VC datalog's records; a torn last line is reported, corruption exits 1."""
    from rich.console import Console
    from rich.table import Table

    from onboard.vc.datalog import DatalogCorruptError, read_datalog

    try:
        replay = read_datalog(file)
    except FileNotFoundError as exc:
        typer.echo(f"{file}: no such datalog", err=True)
        raise typer.Exit(code=1) from exc
    except (DatalogCorruptError, OSError) as exc:
        typer.echo(f"corrupt datalog: {exc}", err=True)
        raise typer.Exit(code=1) from exc
    records = [r for r in replay.records if not kind or r.kind in kind]
    table = Table(title=f"VC datalog {file.name}: {len(records)} of {len(replay.records)} records")
    for column in ("seq", "time [s]", "source", "kind", "payload"):
        table.add_column(column, justify="right" if column in ("seq", "time [s]") else "left")
    for record in records:
        payload = ", ".join(f"{key}={value}" for key, value in record.payload.items())
        table.add_row(str(record.seq), f"{record.time_s:.3f}", record.source, record.kind, payload)
    console = Console(width=120)
    console.print(table)
    if replay.torn_last_line is not None:
        console.print(f"torn last line ignored ({len(replay.torn_last_line)} characters)")


@bench_app.command("trackside")
def bench_trackside(
    vehicles: Annotated[int, typer.Option(min=1, help="Simulated vehicles at 5 Hz.")] = 100,
    seconds: Annotated[float, typer.Option(min=1.0, help="Load duration [s].")] = 20.0,
    rate: Annotated[float, typer.Option(min=1.0, help="REST requests per second.")] = 100.0,
    sockets: Annotated[int, typer.Option(min=1, help="Per-vehicle WebSocket clients.")] = 10,
) -> None:
    """ATO-TS with a simulated fleet and REST load: REST and status-to-browser p50/p99."""
    from deploy.bench.trackside_bench import bench_trackside as run

    run(vehicles=vehicles, seconds=seconds, rate_hz=rate, sockets=sockets)


@bench_app.command("up")
def bench_up(
    vehicles: Annotated[int, typer.Option(min=1, max=100, help="Vehicles brought up.")] = 10,
    drive: Annotated[int, typer.Option(min=0, help="Of them, driven through a journey.")] = 10,
    speed: Annotated[float, typer.Option(min=0.1, max=50.0, help="Onboards' speed.")] = 1.0,
    data_dir: Annotated[
        Path | None, typer.Option(help="Keep the fleet's files (logs, PKI) here.")
    ] = None,
) -> None:
    """ato up with N vehicles, K driven over REST: CPU, memory, liveness, clean shutdown."""
    from rich.console import Console

    from deploy.bench.up_bench import bench_up as run
    from deploy.bench.up_bench import print_up_bench

    result = run(vehicles=vehicles, drive=drive, speed=speed, data_dir=data_dir)
    print_up_bench(result, Console())
    if not result.ok:
        raise typer.Exit(1)


@bench_app.command("zenoh")
def bench_zenoh(
    count: Annotated[int, typer.Option(help="Commands per measurement.")] = 2000,
    warmup: Annotated[int, typer.Option(help="Commands before measuring.")] = 200,
) -> None:
    """Trackside→onboard command round trip, in-process and across processes."""
    from deploy.bench.zenoh_bench import bench_zenoh as run

    run(count=count, warmup=warmup)


def _database_url(database: str | None) -> str:
    """The URL given, else ``ATO_DATABASE_URL``, else the trackside's default."""
    import os

    from trackside.config import Settings

    if database is not None:
        return database
    default: str = Settings.model_fields["database_url"].default
    return os.environ.get("ATO_DATABASE_URL", default)


@contextmanager
def _database_session(database: str | None) -> Iterator[Session]:
    """A session in one transaction on the migrated database, committed on success."""
    from sqlalchemy.orm import Session

    from trackside.db import create_database_engine, migrate

    engine = create_database_engine(_database_url(database))
    try:
        migrate(engine)
        with Session(engine) as session, session.begin():
            yield session
    finally:
        engine.dispose()


@audit_app.command("verify")
def audit_verify(database: DatabaseOption = None) -> None:
    """Recompute the audit log's hash chain: exit 0 if intact, 1 with each break found."""
    from trackside.services.audit_chain import verify

    with _database_session(database) as session:
        report = verify(session)
    if report.intact:
        typer.echo(f"audit log intact: {report.entries} entries chained")
        return
    for problem in report.problems:
        typer.echo(problem, err=True)
    typer.echo(f"audit log TAMPERED: {len(report.problems)} break(s) in {report.entries} entries")
    raise typer.Exit(code=1)
