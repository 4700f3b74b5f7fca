"""``ato``: the one command (CONTRACT.md §1)."""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from protocol import DEFAULT_ROUTER_ENDPOINT, ZenohSettings
from protocol.router import run_router

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

app = typer.Typer(
    help="ato: an open GoA4 ATO over ETCS stack for an unmanned inspection vehicle.",
    no_args_is_help=True,
    add_completion=False,
)
bench_app = typer.Typer(help="Benchmarks that print numbers.", no_args_is_help=True)
app.add_typer(bench_app, name="bench")
trackdb_app = typer.Typer(help="Track data in and out of the database.", no_args_is_help=True)
app.add_typer(trackdb_app, name="trackdb")
vc_app = typer.Typer(help="Vital Control tools.", no_args_is_help=True)
app.add_typer(vc_app, name="vc")

ZenohOption = Annotated[str, typer.Option("--zenoh", help="Zenoh router endpoint to connect to.")]
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
    if not verbose:
        logging.getLogger("alembic").setLevel(logging.WARNING)


@app.command()
def router(
    listen: Annotated[
        list[str] | None, typer.Option("--listen", help="Endpoint to listen on (repeatable).")
    ] = None,
    connect: Annotated[
        list[str] | None, typer.Option("--connect", help="Another router to join (repeatable).")
    ] = None,
    verbose: bool = False,
) -> None:
    """Run a Zenoh router (default tcp/127.0.0.1:7447)."""
    from deploy.processes import stop_on_signals

    _logging(verbose)
    stop = threading.Event()
    with stop_on_signals(stop):
        run_router(stop, listen=listen or [DEFAULT_ROUTER_ENDPOINT], connect=connect or [])


@app.command()
def trackside(
    host: str = "127.0.0.1",
    port: int = 8000,
    zenoh: ZenohOption = DEFAULT_ROUTER_ENDPOINT,
    database: Annotated[
        str | None, typer.Option("--database", help="SQLAlchemy URL (default: ATO_DATABASE_URL)")
    ] = None,
    verbose: bool = False,
) -> None:
    """Run the ATO-TS web service."""
    from trackside.config import Settings
    from trackside.main import main

    _logging(verbose)
    overrides: dict[str, object] = {"zenoh_connect": (zenoh,)}
    if database is not None:
        overrides["database_url"] = database
    main(Settings(**overrides), host=host, port=port)  # type: ignore[arg-type]


@app.command()
def onboard(
    vehicle: Annotated[str, typer.Option("--vehicle", help="Vehicle id, e.g. URV1.")],
    zenoh: ZenohOption = DEFAULT_ROUTER_ENDPOINT,
    line: Annotated[str, typer.Option("--line", help="Line id.")] = "bologna-ring",
    speed: Annotated[float, typer.Option("--speed", help="Simulated s per wall s.")] = 1.0,
    fidelity: Annotated[
        str, typer.Option("--fidelity", help="Plant: point_mass or bogie (VCU + 10-DOF bogie).")
    ] = "point_mass",
    verbose: bool = False,
) -> None:
    """Run one ATO-OB process."""
    from deploy.processes import run_onboard, stop_on_signals

    _logging(verbose)
    if speed <= 0:
        raise typer.BadParameter("--speed must be positive")
    if fidelity not in ("point_mass", "bogie"):
        raise typer.BadParameter("--fidelity must be point_mass or bogie")
    stop = threading.Event()
    with stop_on_signals(stop):
        run_onboard(
            vehicle, zenoh=ZenohSettings(connect=(zenoh,)), line_id=line, speed_factor=speed,
            stop=stop, fidelity=fidelity,  # type: ignore[arg-type]
        )  # fmt: skip


@app.command()
def demo(
    port: int = 8000,
    data_dir: Annotated[Path, typer.Option(help="Where the demo keeps its database.")] = Path(
        ".ato"
    ),
    verbose: bool = False,
) -> None:
    """Router, trackside and URV1 on bologna-ring, with the console on http://127.0.0.1:PORT/."""
    from deploy.demo import run_demo

    _logging(verbose)
    run_demo(port=port, data_dir=data_dir)


@bench_app.command("trackdb")
def bench_trackdb(
    count: Annotated[int, typer.Option(help="Calls per query type.")] = 20000,
) -> None:
    """TrackMap point queries and GPS projection on milano-bologna and bologna-ring."""
    from deploy.bench_trackdb import bench_trackdb as run

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
    from deploy.bench_plant import bench_plant as run

    run(distance_km=distance_km, plots_dir=plots)


@bench_app.command("adf")
def bench_adf(
    plots: Annotated[
        Path | None, typer.Option("--plots", help="Write the RD → AD → RD figure here.")
    ] = None,
) -> None:
    """Plan energies, the RD → AD → RD hand-over, NMPC solve times (ours against IPOPT)."""
    from deploy.bench_adf import bench_adf as run

    run(plots_dir=plots)


@bench_app.command("vc")
def bench_vc(
    seconds: Annotated[float, typer.Option(help="Real-time run length [s].")] = 60.0,
) -> None:
    """VC tasks A/B/C in real time: execution time, lateness at 2 ms, deadline misses."""
    from deploy.bench_vc import bench_vc as run

    if seconds <= 0:
        raise typer.BadParameter("--seconds must be positive")
    run(seconds=seconds)


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


@bench_app.command("zenoh")
def bench_zenoh(
    count: Annotated[int, typer.Option(help="Commands per measurement.")] = 2000,
    warmup: Annotated[int, typer.Option(help="Commands before measuring.")] = 200,
) -> None:
    """Trackside→onboard command round trip, in-process and across processes."""
    from deploy.bench import bench_zenoh as run

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


@trackdb_app.command("import")
def trackdb_import(
    file: Annotated[
        Path, typer.Argument(help="A line document (JSON).", exists=True, dir_okay=False)
    ],
    database: DatabaseOption = None,
) -> None:
    """Validate and import a line; prints its id and version. Invalid: every problem, exit 2."""
    from trackdb import LineValidationError
    from trackdb.storage import import_line

    try:
        with _database_session(database) as session:
            line = import_line(session, file.read_bytes())
    except LineValidationError as exc:
        typer.echo(
            f"{file}: line {exc.line_id!r} rejected, {len(exc.problems)} problem(s):", err=True
        )
        for problem in exc.problems:
            typer.echo(problem, err=True)
        raise typer.Exit(code=2) from exc
    typer.echo(f"{line.id} {line.version()}")


@trackdb_app.command("export")
def trackdb_export(
    line: Annotated[str, typer.Argument(help="Line id.")],
    database: DatabaseOption = None,
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Write to this file, not stdout.")
    ] = None,
    version: Annotated[
        str | None, typer.Option("--version", help="A stored version; the current by default.")
    ] = None,
) -> None:
    """Print a line's canonical JSON (its SHA-256 is the line's version)."""
    from trackdb import LineNotFoundError
    from trackdb.storage import export_line

    try:
        with _database_session(database) as session:
            document = export_line(session, line, version)
    except LineNotFoundError as exc:
        typer.echo(str(exc), err=True)
        raise typer.Exit(code=1) from exc
    if output is None:
        typer.echo(document)
    else:
        output.write_text(document, encoding="utf-8")


@trackdb_app.command("list")
def trackdb_list(database: DatabaseOption = None) -> None:
    """List the stored lines, tab-separated: id, current version, length in metres, name."""
    from trackdb.storage import list_lines

    with _database_session(database) as session:
        summaries = list_lines(session)
    for summary in summaries:
        typer.echo(f"{summary.id}\t{summary.version}\t{summary.length_m:.1f}\t{summary.name}")


@trackdb_app.command("schema")
def trackdb_schema() -> None:
    """Print the JSON Schema of a line document (as in trackdb/line.schema.json)."""
    from trackdb import line_json_schema

    typer.echo(line_json_schema(), nl=False)
