"""``ato bench zenoh``: trackside→onboard command round trip over Zenoh.

Measures the time from the trackside sending a command query to it holding the onboard's
validated acknowledgement, with the real :class:`~onboard.node.OnboardNode` answering:

- in-process, peer to peer: both sessions in this process, one connected to the other;
- in-process, through a router: both sessions and a router in this process;
- across processes: ``ato router`` and ``ato onboard`` as child processes, the trackside here;

each over plain TCP and over TLS with the access control, side by side in one run.
"""

from __future__ import annotations

import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh
from rich.console import Console
from rich.table import Table

from deploy.pki import deployment_pki
from deploy.ports import loopback_endpoint
from deploy.processes import ChildProcess, ato_command
from deploy.stats import percentiles
from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from protocol import (
    LivelinessWatcher,
    RequestTimeoutError,
    TlsFiles,
    ZenohSettings,
    open_session,
    request,
)
from protocol import messages as m
from protocol.access import access_control
from protocol.registry import ALIVE_ONBOARD, COMMAND
from protocol.router import run_router
from trackdb import TrackMap, load_seed_line

__all__ = ["bench_zenoh", "measure_round_trips"]

VEHICLE = "BENCH1"
TRACKSIDE = "ts1"


def measure_round_trips(session: zenoh.Session, *, count: int, warmup: int) -> list[float]:
    """Round-trip times [s] of ``count`` ping commands after ``warmup`` unmeasured ones."""
    samples: list[float] = []
    for index in range(warmup + count):
        command = m.Command(
            vehicle_id=VEHICLE, command_id=index, issued_by="bench", body=m.PingCommand()
        )
        started = time.perf_counter()
        ack = request(session, COMMAND, command, timeout_s=2.0, vehicle=VEHICLE)
        elapsed = time.perf_counter() - started
        if not ack.accepted or ack.command_id != index:
            raise RuntimeError(f"unexpected acknowledgement {ack}")
        if index >= warmup:
            samples.append(elapsed)
    return samples


def _wait_alive(session: zenoh.Session, timeout_s: float) -> None:
    alive = threading.Event()
    key = ALIVE_ONBOARD.format(vehicle=VEHICLE)
    with LivelinessWatcher(session, key, lambda _key, up: alive.set() if up else None):
        if not alive.wait(timeout_s):
            raise RequestTimeoutError(f"{VEHICLE} did not come alive within {timeout_s} s")


@dataclass(frozen=True)
class _Links:
    """Plain TCP links, or TLS with the certificates of ``pki`` and the access control."""

    pki: Path | None

    def endpoint(self) -> str:
        endpoint = loopback_endpoint()
        return endpoint if self.pki is None else endpoint.replace("tcp/", "tls/", 1)

    def tls(self, name: str) -> TlsFiles | None:
        return None if self.pki is None else TlsFiles.of(self.pki, name)

    def rules(self) -> dict[str, Any] | None:
        if self.pki is None:
            return None
        return access_control(vehicles=[VEHICLE], tracksides=[TRACKSIDE])

    def options(self, name: str) -> list[str]:
        return [] if self.pki is None else ["--pki", str(self.pki), "--name", name]


@contextmanager
def _router(endpoint: str, links: _Links) -> Iterator[None]:
    stop, ready = threading.Event(), threading.Event()
    kwargs = {
        "listen": [endpoint],
        "ready": ready,
        "tls": links.tls("router"),
        "access_control": links.rules(),
    }
    thread = threading.Thread(target=run_router, args=(stop,), kwargs=kwargs, daemon=True)
    thread.start()
    ready.wait(10.0)
    try:
        yield
    finally:
        stop.set()
        thread.join(5.0)


@contextmanager
def _onboard_in_process(settings: ZenohSettings) -> Iterator[None]:
    track_map = TrackMap(load_seed_line("bologna-ring"))
    with open_session(settings) as session:
        node = OnboardNode(
            OnboardSettings(vehicle_id=VEHICLE),
            session=session,
            clock=SimClock(),
            track_map=track_map,
        )
        try:
            yield
        finally:
            node.close()


def _in_process_peer(links: _Links, count: int, warmup: int) -> list[float]:
    endpoint = links.endpoint()
    trackside_settings = ZenohSettings(
        mode="peer",
        connect=(),
        listen=(endpoint,),
        tls=links.tls(TRACKSIDE),
        access_control=links.rules(),
    )
    onboard = ZenohSettings(mode="peer", connect=(endpoint,), tls=links.tls(VEHICLE))
    with open_session(trackside_settings) as trackside, _onboard_in_process(onboard):
        _wait_alive(trackside, 5.0)
        return measure_round_trips(trackside, count=count, warmup=warmup)


def _in_process_router(links: _Links, count: int, warmup: int) -> list[float]:
    endpoint = links.endpoint()
    with (
        _router(endpoint, links),
        open_session(ZenohSettings(connect=(endpoint,), tls=links.tls(TRACKSIDE))) as trackside,
        _onboard_in_process(ZenohSettings(connect=(endpoint,), tls=links.tls(VEHICLE))),
    ):
        _wait_alive(trackside, 5.0)
        return measure_round_trips(trackside, count=count, warmup=warmup)


def _across_processes(links: _Links, count: int, warmup: int) -> list[float]:
    endpoint = links.endpoint()
    router = ["router", "--listen", endpoint, *links.options("router")]
    if links.pki is not None:
        router += ["--vehicle", VEHICLE, "--trackside", TRACKSIDE]
    onboard = ["onboard", "--vehicle", VEHICLE, "--zenoh", endpoint, "--no-vc-datalog"]
    onboard += [] if links.pki is None else ["--pki", str(links.pki)]
    with ExitStack() as stack:
        stack.enter_context(ChildProcess(ato_command(*router)))
        stack.enter_context(ChildProcess(ato_command(*onboard)))
        settings = ZenohSettings(connect=(endpoint,), tls=links.tls(TRACKSIDE))
        trackside = stack.enter_context(open_session(settings))
        _wait_alive(trackside, 30.0)
        return measure_round_trips(trackside, count=count, warmup=warmup)


def bench_zenoh(*, count: int, warmup: int) -> dict[str, dict[str, float]]:
    """Run the three measurements, print a table, return the figures [ms]."""
    console = Console(width=110)
    results: dict[str, dict[str, float]] = {}
    cases = {
        "in-process, peer to peer": _in_process_peer,
        "in-process, via router": _in_process_router,
        "across processes, via router": _across_processes,
    }
    with tempfile.TemporaryDirectory(prefix="ato-bench-pki-") as scratch:
        pki = deployment_pki(Path(scratch), vehicles=[VEHICLE], tracksides=[TRACKSIDE])
        for name, run in cases.items():
            # TLS and plain side by side, case by case, in one run.
            for label, links in (("plain TCP", _Links(None)), ("TLS + ACL", _Links(pki))):
                console.print(f"measuring {name}, {label} ({count} commands)…")
                samples = run(links, count, warmup)
                results[f"{name}, {label}"] = _figures(samples)
    _print_table(console, results)
    return results


def _figures(samples: list[float]) -> dict[str, float]:
    median_s, p99_s, max_s = percentiles(samples, (50, 99, 100))
    return {
        "median_ms": median_s * 1e3,
        "p99_ms": p99_s * 1e3,
        "max_ms": max_s * 1e3,
        "count": float(len(samples)),
    }


def _print_table(console: Console, results: dict[str, dict[str, float]]) -> None:
    table = Table(title="trackside→onboard command round trip (ping → CommandAck)")
    for column in ("case", "n", "median [ms]", "p99 [ms]", "max [ms]"):
        table.add_column(column, justify="left" if column == "case" else "right")
    for name, figures in results.items():
        table.add_row(
            name,
            f"{figures['count']:.0f}",
            f"{figures['median_ms']:.3f}",
            f"{figures['p99_ms']:.3f}",
            f"{figures['max_ms']:.3f}",
        )
    console.print(table)
    console.print("target: p99 ≤ 2 ms in-process (TLS's cost: each TLS row beside its plain one)")
