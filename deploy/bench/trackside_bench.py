"""``ato bench trackside``: the service under a simulated fleet and REST load, on loopback.

Four processes, as ``ato up`` lays a deployment out: a Zenoh router of its own; this one runs
ATO-TS (uvicorn, SQLite in a temporary directory); a fleet process publishes the status of
``vehicles`` simulated vehicles at 5 Hz and accepts their commands; a load process runs paced
REST requests (reads, history, commands of a driver holding every vehicle) and per-vehicle
WebSocket clients. Each status carries its wall send time in ``sim_time_s``, so the WebSocket
clients measure status-to-browser latency across processes on one clock. Prints REST p50/p99 and
status-to-browser p50/p99 beside the targets.

The simulated vehicles open no session with the trackside, so its commands go out unsealed, and
they accept them all: a real onboard would refuse them (issue 20). What a command's figure
measures is the trackside's path (REST, hold, audit, Zenoh query, answer), not the onboard's
checks; ``ato bench zenoh`` measures accepted, sealed commands against the real onboard.
"""

from __future__ import annotations

import json
import math
import multiprocessing
import random
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

from rich.console import Console
from rich.table import Table

from deploy.ports import free_tcp_port, loopback_endpoint
from deploy.stats import percentiles
from protocol import (
    TypedPublisher,
    TypedQueryable,
    ZenohSettings,
    declare_liveliness,
    open_session,
)
from protocol import messages as m
from protocol.registry import ALIVE_ONBOARD, COMMAND, STATUS
from protocol.router import run_router

if TYPE_CHECKING:
    import uvicorn

__all__ = [
    "BenchFigures",
    "bench_trackside",
    "FleetSchedule",
    "fleet_process",
    "load_process",
    "router_process",
]

REST_P99_TARGET_MS = 50.0
LIVE_P99_TARGET_MS = 100.0
STATUS_PERIOD_S = 0.2
FLEET_TICK_S = 0.001
"""How often the simulated fleet publishes the reports fallen due [s]."""
FLEET_SEED = 20261207
ADMIN = ("bench-admin", "bench-password")
KINDS = (
    "GET /vehicles",
    "GET /vehicles/{id}",
    "GET …/telemetry",
    "GET …/events",
    "POST …/rd-target-speed",
)


@dataclass(frozen=True)
class BenchFigures:
    rest_ms: dict[str, float]
    live_ms: dict[str, float]
    requests: int
    frames: int
    rest_errors: int
    rest_by_kind_ms: dict[str, dict[str, float]]
    rest_error_codes: dict[str, int] = field(default_factory=dict)
    """The answers ≥ 400 by request kind and status code."""
    service_within_s: dict[float, float] = field(default_factory=dict)
    """The service's own REST histogram over the load (``/metrics``, from the ASGI call to the
    answer's end; no client, no socket): the requests within each bucket's bound [s]."""


class _LoadFigures(TypedDict):
    """What :func:`load_process` puts on its queue: durations and latencies [s]."""

    rest: list[float]
    by_kind: dict[str, list[float]]
    errors: int
    error_codes: dict[str, int]
    live: list[float]
    service: dict[float, float]
    """The service's own REST histogram over the load: requests timed within each bound [s]."""


REST_HISTOGRAM = "ato_ts_rest_request_seconds"


def _service_histogram(client: Any) -> dict[float, float]:
    """The service's REST latency histogram (``GET /metrics``, from loopback): the requests
    timed within each bucket's bound [s], every route but the scrape's own."""
    from prometheus_client.parser import text_string_to_metric_families

    within: dict[float, float] = {}
    for family in text_string_to_metric_families(client.get("/metrics").text):
        if family.name != REST_HISTOGRAM:
            continue
        for sample in family.samples:
            if sample.name.endswith("_bucket") and sample.labels.get("route") != "/metrics":
                bound = float(sample.labels["le"])
                within[bound] = within.get(bound, 0.0) + sample.value
    return within


def service_share_within(service: dict[float, float], bound_ms: float) -> float | None:
    """The share of the load's requests the service itself timed within ``bound_ms`` (a
    bucket's bound), or None without requests."""
    total = service.get(math.inf, 0.0)
    if total <= 0:
        return None
    return service.get(bound_ms / 1e3, 0.0) / total


def _vehicle_id(index: int) -> str:
    return f"SIM{index:03d}"


def _report(vehicle: str, seq: int) -> m.StatusReport:
    return m.StatusReport(
        vehicle_id=vehicle,
        seq=seq,
        sim_time_s=time.time(),
        line_id="bologna-ring",
        position_m=float(seq),
        speed_mps=10.0,
        acceleration_mps2=0.0,
        traction_force_n=1000.0,
        ato_state=m.AtoState.ENGAGED,
        etcs_mode=m.EtcsMode.FS,
        sc_state=m.ScState.AD,
    )


class FleetSchedule:
    """When each simulated vehicle reports: every :data:`STATUS_PERIOD_S`, at an offset in the
    period drawn at random (seeded), as independent vehicles' clocks are, so that the reports
    reach the trackside as a fleet's do (a Poisson stream of ``vehicles`` / period a second),
    not one every period / ``vehicles``."""

    def __init__(self, vehicles: int, seed: int = FLEET_SEED) -> None:
        draw = random.Random(seed)
        phases = [draw.uniform(0.0, STATUS_PERIOD_S) for _ in range(vehicles)]
        self._order = sorted((phase, index) for index, phase in enumerate(phases))
        self.sent = 0
        """Reports fallen due so far, over every period."""

    def due(self, elapsed_s: float) -> Iterator[tuple[int, int]]:
        """The reports fallen due by ``elapsed_s`` since the start and not taken yet, in time
        order: (vehicle index, report number)."""
        while True:
            seq, slot = divmod(self.sent, len(self._order))
            phase, index = self._order[slot]
            if seq * STATUS_PERIOD_S + phase > elapsed_s:
                return
            self.sent += 1
            yield index, seq


def fleet_process(
    endpoint: str, vehicles: int, seconds: float, ready: Any, stop: Any | None = None
) -> None:
    """Publish every vehicle's status at 5 Hz, each at its own phase (:class:`FleetSchedule`);
    answer commands; for ``seconds`` at most, or until ``stop`` is set.

    The process wakes every :data:`FLEET_TICK_S` and publishes the reports that fell due since:
    the arrivals of independent vehicles, to a millisecond. Woken for each report, one
    interpreter took most of a core to send five thousand a second and left the service the
    other (docs/trackside.md, "Fifth sitting")."""
    with open_session(ZenohSettings(connect=(endpoint,))) as session:
        ids = [_vehicle_id(index) for index in range(vehicles)]
        tokens = [declare_liveliness(session, ALIVE_ONBOARD.format(vehicle=v)) for v in ids]
        publishers = [TypedPublisher(session, STATUS, vehicle=v) for v in ids]

        def answer(_chunks: dict[str, str], command: m.Command) -> m.CommandAck:
            # Unsealed (no session): accepted all the same, see the module's docstring.
            return m.CommandAck(
                vehicle_id=command.vehicle_id,
                command_id=command.command_id,
                accepted=True,
                sim_time_s=time.time(),
            )

        commands = TypedQueryable(session, COMMAND, answer)
        ready.set()
        schedule = FleetSchedule(vehicles)
        started = time.monotonic()
        idle = threading.Event()
        while (elapsed := time.monotonic() - started) < seconds and not (
            stop is not None and stop.is_set()
        ):
            for index, seq in schedule.due(elapsed):
                publishers[index].put(_report(ids[index], seq))
            idle.wait(FLEET_TICK_S)
        commands.close()
        for publisher in publishers:
            publisher.close()
        for token in tokens:
            token.undeclare()


def _percentiles(samples: list[float]) -> dict[str, float]:
    if not samples:
        return {"p50": float("nan"), "p99": float("nan"), "max": float("nan"), "n": 0.0}
    p50, p99, top = percentiles(samples, (50, 99, 100))
    return {"p50": p50, "p99": p99, "max": top, "n": float(len(samples))}


def _rest_worker(
    base_url: str,
    headers: dict[str, str],
    vehicles: int,
    rate_hz: float,
    seconds: float,
    worker: int,
    out: list[tuple[float, int, str]],
    offset_s: float = 0.0,
) -> None:
    """Requests at ``rate_hz`` for ``seconds``, the first after ``offset_s``: each worker
    offset by its share of the period and starting at another kind, so that the workers
    together send one request every 1 / (workers × ``rate_hz``), of every kind in turn (all
    started at once, they sent four requests of one kind at the same instant, four commands
    together behind one another's audit entries)."""
    import httpx

    with httpx.Client(base_url=base_url, headers=headers, timeout=10.0) as client:
        started = time.monotonic() + offset_s
        count = 0
        idle = threading.Event()
        while (now := time.monotonic()) - started < seconds:
            idle.wait(max(0.0, started + count / rate_hz - now))
            vehicle = _vehicle_id((worker * 7 + count) % vehicles)
            kind = (worker + count) % len(KINDS)
            sent = time.perf_counter()
            if kind == 0:
                response = client.get("/api/v1/vehicles")
            elif kind == 1:
                response = client.get(f"/api/v1/vehicles/{vehicle}")
            elif kind == 2:
                response = client.get(f"/api/v1/vehicles/{vehicle}/telemetry?limit=60")
            elif kind == 3:
                response = client.get(f"/api/v1/vehicles/{vehicle}/events?limit=50")
            else:
                response = client.post(
                    f"/api/v1/vehicles/{vehicle}/rd-target-speed", json={"target_speed_kmh": 30.0}
                )
            out.append((time.perf_counter() - sent, response.status_code, KINDS[kind]))
            count += 1


def _live_client(url: str, token: str, seconds: float, out: list[float]) -> None:
    from websockets.sync.client import connect

    deadline = time.monotonic() + seconds
    with connect(url) as socket:
        socket.send(json.dumps({"type": "auth", "token": token}))  # never in the URL
        while time.monotonic() < deadline:
            try:
                frame = json.loads(socket.recv(timeout=1.0))
            except TimeoutError:
                continue
            if frame["type"] == "status":
                out.append(time.time() - frame["status"]["sim_time_s"])


def load_process(
    base_url: str, vehicles: int, rate_hz: float, seconds: float, sockets: int, results: Any
) -> None:
    """Select every vehicle, then run the REST workers and WebSocket clients; put the
    figures on ``results``."""
    import httpx

    with httpx.Client(base_url=base_url, timeout=30.0) as client:
        form = {"username": ADMIN[0], "password": ADMIN[1]}
        token = client.post("/api/v1/auth/token", data=form).json()["access_token"]
        headers = {"Authorization": f"Bearer {token}"}
        for index in range(vehicles):
            client.post(f"/api/v1/vehicles/{_vehicle_id(index)}/select", headers=headers)
        # The selections changed every hold: the fleet's list is built once here, as a console
        # open before the load would have had it, not by the load's first requests (the load
        # measures the steady state; a list built after a change is timed in docs/trackside.md).
        client.get("/api/v1/vehicles", headers=headers)
        before = _service_histogram(client)
    workers = 4
    rest: list[list[tuple[float, int, str]]] = [[] for _ in range(workers)]
    live: list[list[float]] = [[] for _ in range(sockets)]
    ws_base = base_url.replace("http://", "ws://")
    threads = [
        threading.Thread(
            target=_rest_worker,
            args=(base_url, headers, vehicles, rate_hz / workers, seconds, worker, rest[worker]),
            kwargs={"offset_s": worker / rate_hz},
        )
        for worker in range(workers)
    ] + [
        threading.Thread(
            target=_live_client,
            args=(
                f"{ws_base}/api/v1/ws/vehicles/{_vehicle_id(index * vehicles // max(1, sockets))}",
                token,
                seconds,
                live[index],
            ),
        )
        for index in range(sockets)
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    with httpx.Client(base_url=base_url, timeout=30.0) as client:
        after = _service_histogram(client)
    samples = [sample for part in rest for sample in part]
    results.put(
        {
            "rest": [duration for duration, _, _ in samples],
            "by_kind": {kind: [d for d, _, k in samples if k == kind] for kind in KINDS},
            "errors": sum(1 for _, code, _ in samples if code >= 400),
            "error_codes": dict(
                Counter(f"{kind} {code}" for _, code, kind in samples if code >= 400)
            ),
            "live": [latency for part in live for latency in part],
            "service": {bound: count - before.get(bound, 0.0) for bound, count in after.items()},
        }
    )


def run_bench(
    *,
    vehicles: int = 100,
    seconds: float = 20.0,
    rate_hz: float = 100.0,
    sockets: int = 10,
    warmup_s: float = 3.0,
) -> BenchFigures:
    """Run the three processes and return the figures [ms]."""
    endpoint = loopback_endpoint()
    stop = threading.Event()
    router, router_stop = _start_router(endpoint)
    try:
        with tempfile.TemporaryDirectory() as scratch:
            server, serving, port = _start_service(Path(scratch), endpoint, stop)
            figures = _run_fleet_and_load(
                endpoint,
                f"http://127.0.0.1:{port}",
                vehicles=vehicles,
                seconds=seconds,
                rate_hz=rate_hz,
                sockets=sockets,
                warmup_s=warmup_s,
                stop=stop,
            )
            server.should_exit = True
            serving.join(10.0)
    finally:
        stop.set()
        router_stop.set()
        router.join(10.0)
    return _bench_figures(figures)


def router_process(endpoint: str, ready: Any, stop: Any) -> None:
    """A Zenoh router on ``endpoint``, in a process of its own as ``ato up`` runs it: ``ready``
    is set once it listens, it closes when ``stop`` is set."""
    closing = threading.Event()
    listening = threading.Event()
    router = threading.Thread(
        target=run_router,
        args=(closing,),
        daemon=True,
        kwargs={"listen": [endpoint], "ready": listening},
    )
    router.start()
    if listening.wait(10.0):
        ready.set()
    stop.wait()
    closing.set()
    router.join(10.0)


def _start_router(endpoint: str) -> tuple[Any, Any]:
    """:func:`router_process` started, once it listens: (the process, its stop event)."""
    spawn = multiprocessing.get_context("spawn")
    ready, stop = spawn.Event(), spawn.Event()
    router = spawn.Process(target=router_process, args=(endpoint, ready, stop), daemon=True)
    router.start()
    if not ready.wait(30.0):
        router.terminate()
        raise RuntimeError("the Zenoh router did not start")
    return router, stop


def _start_service(
    scratch: Path, endpoint: str, stop: threading.Event
) -> tuple[uvicorn.Server, threading.Thread, int]:
    """ATO-TS under uvicorn in a thread, its database in ``scratch``, once it has started:
    (server, its thread, its port)."""
    import uvicorn

    from trackside.config import Settings
    from trackside.main import create_app

    port = free_tcp_port()
    settings = Settings(
        database_url=f"sqlite:///{scratch / 'bench.db'}",
        zenoh_connect=(endpoint,),
        admin_user=ADMIN[0],
        admin_password=ADMIN[1],
        seed_lines=False,
    )
    server = uvicorn.Server(
        uvicorn.Config(create_app(settings), host="127.0.0.1", port=port, log_level="warning")
    )
    serving = threading.Thread(target=server.run, daemon=True)
    serving.start()
    while not server.started:
        stop.wait(0.05)
    return server, serving, port


def _run_fleet_and_load(
    endpoint: str,
    base_url: str,
    *,
    vehicles: int,
    seconds: float,
    rate_hz: float,
    sockets: int,
    warmup_s: float,
    stop: threading.Event,
) -> _LoadFigures:
    """The fleet process, and once every vehicle reports, the load process: its raw figures
    [s], as :func:`load_process` puts them."""
    spawn = multiprocessing.get_context("spawn")
    fleet_ready = spawn.Event()
    # The fleet lives until the load is done: selecting a thousand vehicles before the load
    # takes tens of seconds, and a fleet timed to the load alone left while it ran (every
    # command to its vehicles then answered 404, not alive).
    fleet_stop = spawn.Event()
    fleet_s = seconds + warmup_s + 120.0 + vehicles * 0.1
    fleet = spawn.Process(
        target=fleet_process, args=(endpoint, vehicles, fleet_s, fleet_ready, fleet_stop)
    )
    fleet.start()
    fleet_ready.wait(30.0)
    stop.wait(warmup_s)  # every vehicle seen alive and reporting
    results = spawn.Queue()
    load = spawn.Process(
        target=load_process, args=(base_url, vehicles, rate_hz, seconds, sockets, results)
    )
    load.start()
    figures: _LoadFigures = results.get(timeout=seconds + 120.0)
    load.join(10.0)
    fleet_stop.set()
    fleet.join(10.0)
    fleet.terminate()
    fleet.join(10.0)
    return figures


def _bench_figures(figures: _LoadFigures) -> BenchFigures:
    """The load process's raw figures [s] as percentiles [ms]."""
    rest = _percentiles([value * 1e3 for value in figures["rest"]])
    live = _percentiles([value * 1e3 for value in figures["live"]])
    by_kind = {
        kind: _percentiles([value * 1e3 for value in values])
        for kind, values in figures["by_kind"].items()
    }
    return BenchFigures(
        rest_ms=rest,
        live_ms=live,
        requests=len(figures["rest"]),
        frames=len(figures["live"]),
        rest_errors=figures["errors"],
        rest_error_codes=figures["error_codes"],
        rest_by_kind_ms=by_kind,
        service_within_s=figures["service"],
    )


def bench_trackside(*, vehicles: int, seconds: float, rate_hz: float, sockets: int) -> BenchFigures:
    """Run the bench and print the figures beside the targets."""
    console = Console(width=100)
    console.print(
        f"{vehicles} vehicles at {1 / STATUS_PERIOD_S:.0f} Hz, REST at {rate_hz:.0f} req/s and "
        f"{sockets} WebSocket clients for {seconds:.0f} s…"
    )
    figures = run_bench(vehicles=vehicles, seconds=seconds, rate_hz=rate_hz, sockets=sockets)
    table = Table(title="ATO-TS under load (loopback)")
    for column in ("measure", "n", "p50 [ms]", "p99 [ms]", "max [ms]", "target p99 [ms]"):
        table.add_column(column, justify="left" if column == "measure" else "right")
    rows = [("REST request → response", figures.rest_ms, REST_P99_TARGET_MS)]
    rows += [
        (f"  {kind}", values, REST_P99_TARGET_MS)
        for kind, values in figures.rest_by_kind_ms.items()
    ]
    rows.append(("status → browser (WebSocket)", figures.live_ms, LIVE_P99_TARGET_MS))
    for name, values, target in rows:
        table.add_row(
            name,
            f"{values['n']:.0f}",
            f"{values['p50']:.1f}",
            f"{values['p99']:.1f}",
            f"{values['max']:.1f}",
            f"≤ {target:.0f}",
        )
    console.print(table)
    codes = ", ".join(f"{what}: {n}" for what, n in sorted(figures.rest_error_codes.items()))
    console.print(f"REST answers ≥ 400: {figures.rest_errors}" + (f" ({codes})" if codes else ""))
    share = service_share_within(figures.service_within_s, REST_P99_TARGET_MS)
    if share is not None:
        console.print(
            f"The service's own REST histogram (/metrics: from the ASGI call to the answer's "
            f"end, no client): {100 * share:.1f} % within {REST_P99_TARGET_MS:.0f} ms"
        )
    return figures
