"""``ato``: the one command (CONTRACT.md §1)."""

from __future__ import annotations

import logging
import threading
from pathlib import Path
from typing import Annotated

import typer

from protocol import DEFAULT_ROUTER_ENDPOINT, ZenohSettings
from protocol.router import run_router

app = typer.Typer(
    help="ato: an open GoA4 ATO over ETCS stack for an unmanned inspection vehicle.",
    no_args_is_help=True,
    add_completion=False,
)
bench_app = typer.Typer(help="Benchmarks that print numbers.", no_args_is_help=True)
app.add_typer(bench_app, name="bench")

ZenohOption = Annotated[str, typer.Option("--zenoh", help="Zenoh router endpoint to connect to.")]


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
    verbose: bool = False,
) -> None:
    """Run one ATO-OB process."""
    from deploy.processes import run_onboard, stop_on_signals

    _logging(verbose)
    if speed <= 0:
        raise typer.BadParameter("--speed must be positive")
    stop = threading.Event()
    with stop_on_signals(stop):
        run_onboard(
            vehicle, zenoh=ZenohSettings(connect=(zenoh,)), line_id=line, speed_factor=speed,
            stop=stop,
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


@bench_app.command("zenoh")
def bench_zenoh(
    count: Annotated[int, typer.Option(help="Commands per measurement.")] = 2000,
    warmup: Annotated[int, typer.Option(help="Commands before measuring.")] = 200,
) -> None:
    """Trackside→onboard command round trip, in-process and across processes."""
    from deploy.bench import bench_zenoh as run

    run(count=count, warmup=warmup)
