"""``ato demo``: router, trackside and URV1 on bologna-ring, driven remotely at 30 km/h.

The router runs in this process, URV1 in a child process, and the trackside serves the console
here. A demo driver asks URV1 for 30 km/h in remote driving, as at the start of the seed 000 field
test. The demo account is the only fixed password ``ato`` has; it exists only in the demo's own
database.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path

from rich.console import Console

from deploy.pki import deployment_pki
from deploy.processes import ChildProcess, ato_command
from protocol import (
    LivelinessWatcher,
    ProtocolError,
    TlsFiles,
    ZenohSettings,
    open_session,
    request,
)
from protocol import messages as m
from protocol.access import access_control
from protocol.registry import ALIVE_ONBOARD, COMMAND
from protocol.router import run_router
from protocol.units import MPS_PER_KMH

__all__ = ["DEMO_PASSWORD", "DEMO_USER", "DEMO_VEHICLE", "run_demo"]

DEMO_USER = "demo"
DEMO_PASSWORD = "ato-demo"
DEMO_VEHICLE = "URV1"
DEMO_ROUTER = "tls/127.0.0.1:7447"
DEMO_DRIVER = "demo-driver"
"""The demo's driver commands URV1 over Zenoh as a trackside service does, with a trackside
certificate of its own (only tracksides may command a vehicle)."""
DEMO_TARGET_SPEED_MPS = 30.0 * MPS_PER_KMH

_log = logging.getLogger(__name__)


def _demo_driver(stop: threading.Event, pki: Path) -> None:
    """Once URV1 is alive, ask it for the demo speed until it accepts (the trackside's simulated
    operator answers the Vital Control's requests)."""
    settings = ZenohSettings(connect=(DEMO_ROUTER,), tls=TlsFiles.of(pki, DEMO_DRIVER))
    with open_session(settings) as session:
        alive = threading.Event()
        key = ALIVE_ONBOARD.format(vehicle=DEMO_VEHICLE)
        with LivelinessWatcher(session, key, lambda _key, up: alive.set() if up else None):
            command_id = 0
            while not stop.is_set():
                if not alive.wait(0.5):
                    continue
                command = m.Command(
                    vehicle_id=DEMO_VEHICLE,
                    command_id=command_id,
                    issued_by="demo-driver",
                    body=m.RemoteDrivingTargetCommand(target_speed_mps=DEMO_TARGET_SPEED_MPS),
                )
                command_id += 1
                try:
                    ack = request(session, COMMAND, command, vehicle=DEMO_VEHICLE)
                except ProtocolError as exc:
                    _log.warning("demo driver: %s", exc)
                    stop.wait(1.0)
                    continue
                if ack.accepted:
                    _log.info("demo driver: %s accepted 30 km/h", DEMO_VEHICLE)
                    break
                stop.wait(1.0)
            stop.wait()


def _start_router(stop: threading.Event, pki: Path, *, tracksides: list[str]) -> threading.Thread:
    """The demo's router on a thread, TLS with the access control; started and listening."""
    ready = threading.Event()
    router = threading.Thread(
        target=run_router,
        args=(stop,),
        kwargs={
            "listen": [DEMO_ROUTER],
            "ready": ready,
            "tls": TlsFiles.of(pki, "router"),
            "access_control": access_control(vehicles=[DEMO_VEHICLE], tracksides=tracksides),
        },
        name="zenoh-router",
        daemon=True,
    )
    router.start()
    if not ready.wait(10.0):
        raise SystemExit(f"the Zenoh router did not start on {DEMO_ROUTER} (port taken?)")
    return router


def run_demo(*, port: int, data_dir: Path) -> None:
    import uvicorn

    from trackside.config import Settings
    from trackside.main import create_app

    data_dir.mkdir(parents=True, exist_ok=True)
    trackside = "ts1"
    pki = deployment_pki(
        data_dir / "pki", vehicles=[DEMO_VEHICLE], tracksides=[trackside, DEMO_DRIVER]
    )
    stop = threading.Event()
    router = _start_router(stop, pki, tracksides=[trackside, DEMO_DRIVER])

    settings = Settings(
        database_url=f"sqlite:///{(data_dir / 'demo.db').resolve()}",
        zenoh_connect=(DEMO_ROUTER,),
        zenoh_pki_dir=pki,
        instance_id=trackside,
        admin_user=DEMO_USER,
        admin_password=DEMO_PASSWORD,
        simulated_operators=(DEMO_VEHICLE,),
    )
    # The vehicle's VC: two boards in 2-out-of-2 (the default), recording its datalog.
    datalog = data_dir / "vc" / f"{DEMO_VEHICLE}.jsonl"
    onboard_args = ato_command(
        "onboard",
        "--vehicle",
        DEMO_VEHICLE,
        "--zenoh",
        DEMO_ROUTER,
        "--vc-datalog",
        str(datalog),
        "--pki",
        str(pki),
    )
    onboard = ChildProcess(
        onboard_args,
        name=f"onboard-{DEMO_VEHICLE}",
        log_file=data_dir / f"onboard-{DEMO_VEHICLE}.log",
    )
    with onboard:
        driver = threading.Thread(target=_demo_driver, args=(stop, pki), daemon=True)
        driver.start()
        console = Console()
        console.rule("[bold]ato demo")
        console.print(f"Console:  [bold]http://127.0.0.1:{port}/[/bold]")
        console.print(
            f"Login:    user [bold]{DEMO_USER}[/bold]  password [bold]{DEMO_PASSWORD}[/bold]"
        )
        console.print(f"Vehicle:  {DEMO_VEHICLE} on bologna-ring, remote driving at 30 km/h")
        console.print(f"Zenoh:    {DEMO_ROUTER}, TLS and access control (certificates in {pki})")
        console.print(f"VC:       2-out-of-2, datalog {datalog} (ato vc replay)")
        console.print(f"Logs:     {data_dir}/   Stop with Ctrl-C")
        console.rule()
        try:
            uvicorn.run(create_app(settings), host="127.0.0.1", port=port, log_level="warning")
        finally:
            stop.set()
    router.join(5.0)
