"""``ato demo``: router, trackside and URV1 on bologna-ring, driven remotely at 30 km/h.

``--line ID`` puts URV1 on another line the demo's database holds: a built-in one, or one
imported beforehand (``ato trackdb import FILE --database sqlite:///.ato/demo.db``); the demo
imports nothing itself. URV1 has no line built in: it gets its line from the demo's trackside
over Zenoh and keeps a verified copy in ``DATA_DIR/track/URV1``.

The router runs in this process, URV1 in a child process, and the trackside serves the console
here. A demo driver asks URV1 for 30 km/h in remote driving, as at the start of the seed 000 field
test: as a control-room operator would, through the trackside's REST API as the demo user (the
trackside seals the command for URV1's session; the onboard takes no other). The demo account is
the only fixed password ``ato`` has; it exists only in the demo's own database.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path

import httpx
from rich.console import Console

from deploy.pki import deployment_pki
from deploy.processes import ChildProcess, ato_command
from protocol import TlsFiles
from protocol.access import access_control
from protocol.router import run_router

__all__ = ["DEMO_PASSWORD", "DEMO_USER", "DEMO_VEHICLE", "run_demo"]

DEMO_USER = "demo"
DEMO_PASSWORD = "ato-demo"
DEMO_VEHICLE = "URV1"
DEMO_ROUTER = "tls/127.0.0.1:7447"
DEMO_LINE = "bologna-ring"
DEMO_TARGET_SPEED_KMH = 30.0
DEMO_DRIVER_RETRY_S = 1.0
"""Wall time between two attempts of the demo driver (service starting, URV1 not alive yet,
or not yet in session with the trackside)."""

_log = logging.getLogger(__name__)


def _demo_driver(stop: threading.Event, base_url: str, line_id: str = DEMO_LINE) -> None:
    """Log in as the demo user, hold URV1 and ask it for the demo speed until it accepts (the
    trackside's simulated operator answers the Vital Control's requests). A line the demo's
    database lacks is reported: URV1 waits for it."""
    with httpx.Client(base_url=base_url, timeout=10.0) as client:
        while not stop.is_set():
            try:
                if not _line_stored(client, line_id):
                    _log.error(
                        "line %s is not in the demo's database: import it "
                        "(ato trackdb import FILE --database ...); %s waits for it",
                        line_id,
                        DEMO_VEHICLE,
                    )
                    return
                if _drive_demo_vehicle(client):
                    _log.info(
                        "demo driver: %s accepted %g km/h", DEMO_VEHICLE, DEMO_TARGET_SPEED_KMH
                    )
                    return
            except httpx.HTTPStatusError as exc:  # the login refused: retrying would lock it
                _log.warning("demo driver: %s; %s is not driven", exc, DEMO_VEHICLE)
                return
            except httpx.HTTPError as exc:  # the service is not serving yet, or is going
                _log.debug("demo driver: %s", exc)
            stop.wait(DEMO_DRIVER_RETRY_S)


def _log_in(client: httpx.Client) -> None:
    """The demo user's bearer token on the client (once)."""
    if "Authorization" not in client.headers:
        login = client.post(
            "/api/v1/auth/token", data={"username": DEMO_USER, "password": DEMO_PASSWORD}
        )
        login.raise_for_status()
        client.headers["Authorization"] = f"Bearer {login.json()['access_token']}"


def _line_stored(client: httpx.Client, line_id: str) -> bool:
    """Whether the demo's trackside holds the line (raises while the service is starting)."""
    _log_in(client)
    answer = client.get(f"/api/v1/lines/{line_id}/version")
    if answer.status_code == httpx.codes.NOT_FOUND:
        return False
    answer.raise_for_status()
    return True


def _drive_demo_vehicle(client: httpx.Client) -> bool:
    """One attempt: log in (once), select URV1, ask for the demo speed; True once accepted."""
    _log_in(client)
    vehicle = f"/api/v1/vehicles/{DEMO_VEHICLE}"
    if client.post(f"{vehicle}/select").status_code != httpx.codes.OK:
        return False  # URV1 not seen yet
    answer = client.post(
        f"{vehicle}/rd-target-speed", json={"target_speed_kmh": DEMO_TARGET_SPEED_KMH}
    )
    if answer.status_code != httpx.codes.OK:
        return False  # not alive yet, or did not answer in time
    ack = answer.json()
    if not ack["accepted"]:
        _log.info("demo driver: %s refused: %s", DEMO_VEHICLE, ack["reason"])
    return bool(ack["accepted"])


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


def run_demo(*, port: int, data_dir: Path, line_id: str = DEMO_LINE) -> None:
    import uvicorn

    from trackside.config import Settings
    from trackside.main import create_app

    data_dir.mkdir(parents=True, exist_ok=True)
    trackside = "ts1"
    pki = deployment_pki(data_dir / "pki", vehicles=[DEMO_VEHICLE], tracksides=[trackside])
    stop = threading.Event()
    router = _start_router(stop, pki, tracksides=[trackside])

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
        "--line",
        line_id,
        "--track-dir",
        str(data_dir / "track" / DEMO_VEHICLE),
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
        base_url = f"http://127.0.0.1:{port}"
        driver = threading.Thread(target=_demo_driver, args=(stop, base_url, line_id), daemon=True)
        driver.start()
        _print_banner(port, pki, datalog, data_dir, line_id)
        try:
            uvicorn.run(create_app(settings), host="127.0.0.1", port=port, log_level="warning")
        finally:
            stop.set()
    router.join(5.0)


def _print_banner(port: int, pki: Path, datalog: Path, data_dir: Path, line_id: str) -> None:
    """Where the console is, how to log in, what runs."""
    console = Console()
    console.rule("[bold]ato demo")
    console.print(f"Console:  [bold]http://127.0.0.1:{port}/[/bold]")
    console.print(f"Login:    user [bold]{DEMO_USER}[/bold]  password [bold]{DEMO_PASSWORD}[/bold]")
    console.print(
        f"Vehicle:  {DEMO_VEHICLE} on {line_id}, remote driving at {DEMO_TARGET_SPEED_KMH:g} km/h"
    )
    console.print(f"Zenoh:    {DEMO_ROUTER}, TLS and access control (certificates in {pki})")
    console.print(f"VC:       2-out-of-2, datalog {datalog} (ato vc replay)")
    console.print(f"Logs:     {data_dir}/   Stop with Ctrl-C")
    console.rule()
