"""``ato bench zenoh``: trackside→onboard command round trip over Zenoh.

Measures the time from the trackside sending a command query to it holding the onboard's
validated acknowledgement, with the real :class:`~onboard.node.OnboardNode` answering. The
trackside is a real :class:`~trackside.bridge.ZenohBridge`: the vehicle opens its session with
it first, and each ping goes out sealed for that session (the onboard refuses any other, issue
20), so what is measured is an accepted command, sealing and checks included:

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
from protocol import RequestTimeoutError, TlsFiles, ZenohSettings, open_session
from protocol import messages as m
from protocol.access import access_control
from protocol.router import run_router
from trackdb import TrackMap, load_seed_line
from trackside.bridge import ZenohBridge

__all__ = ["bench_zenoh", "measure_round_trips", "open_vehicle_session", "trackside_bridge"]

VEHICLE = "BENCH1"
TRACKSIDE = "ts1"
LINE = "bologna-ring"
STEP_S = 0.1
"""Simulated time an in-process node is run for at a time while it opens its session [s]."""


def measure_round_trips(bridge: ZenohBridge, *, count: int, warmup: int) -> list[float]:
    """Round-trip times [s] of ``count`` ping commands after ``warmup`` unmeasured ones, sent
    through the trackside's ``bridge`` (sealed for the vehicle's session: open it first with
    :func:`open_vehicle_session`); each must be accepted."""
    samples: list[float] = []
    for index in range(warmup + count):
        command = m.Command(
            vehicle_id=VEHICLE, command_id=index, issued_by="bench", body=m.PingCommand()
        )
        started = time.perf_counter()
        ack = bridge.command(command, timeout_s=2.0)
        elapsed = time.perf_counter() - started
        if not ack.accepted:
            raise RuntimeError(f"{VEHICLE} refused ping {index}: {ack.reason}")
        if index >= warmup:
            samples.append(elapsed)
    return samples


def trackside_bridge(session: zenoh.Session) -> ZenohBridge:
    """The bench's trackside, as ATO-TS's: it answers the vehicle's handshake and its query for
    the line's version, acknowledges its reports and seals each command for its session."""
    version = TrackMap(load_seed_line(LINE)).version
    return ZenohBridge(
        session,
        instance_id=TRACKSIDE,
        line_version=lambda line_id: version if line_id == LINE else None,
    )


def open_vehicle_session(
    bridge: ZenohBridge, timeout_s: float, *, node: OnboardNode | None = None
) -> None:
    """Wait (wall time) until the vehicle holds a session with ``bridge`` and takes its
    commands: a ping through it is accepted (the vehicle takes the handshake's answer at its
    next session tick, after the trackside has opened its side). An in-process ``node`` that
    nothing runs is run meanwhile, :data:`STEP_S` at a time: its handshake is one of its tasks.
    Raises :class:`~protocol.RequestTimeoutError` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    ping = m.Command(vehicle_id=VEHICLE, command_id=0, issued_by="bench", body=m.PingCommand())
    changed = threading.Event()  # set by each report, handshake and liveliness change
    bridge.add_listener(changed.set)
    try:
        while not (bridge.session_open(VEHICLE) and bridge.command(ping, timeout_s=2.0).accepted):
            if time.monotonic() > deadline:
                raise RequestTimeoutError(f"{VEHICLE} opened no session within {timeout_s} s")
            if node is None:
                changed.wait(STEP_S)
                changed.clear()
            else:
                node.run(STEP_S)
    finally:
        bridge.remove_listener(changed.set)


@contextmanager
def _trackside(settings: ZenohSettings) -> Iterator[ZenohBridge]:
    with open_session(settings) as session:
        bridge = trackside_bridge(session)
        try:
            yield bridge
        finally:
            bridge.close()


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
def _onboard_in_process(settings: ZenohSettings) -> Iterator[OnboardNode]:
    track_map = TrackMap(load_seed_line(LINE))
    with open_session(settings) as session:
        node = OnboardNode(
            OnboardSettings(vehicle_id=VEHICLE),
            session=session,
            clock=SimClock(),
            track_map=track_map,
        )
        try:
            yield node
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
    with _trackside(trackside_settings) as trackside, _onboard_in_process(onboard) as node:
        open_vehicle_session(trackside, 5.0, node=node)
        return measure_round_trips(trackside, count=count, warmup=warmup)


def _in_process_router(links: _Links, count: int, warmup: int) -> list[float]:
    endpoint = links.endpoint()
    with (
        _router(endpoint, links),
        _trackside(ZenohSettings(connect=(endpoint,), tls=links.tls(TRACKSIDE))) as trackside,
        _onboard_in_process(ZenohSettings(connect=(endpoint,), tls=links.tls(VEHICLE))) as node,
    ):
        open_vehicle_session(trackside, 5.0, node=node)
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
        trackside = stack.enter_context(_trackside(settings))
        open_vehicle_session(trackside, 30.0)
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
    table = Table(title="trackside→onboard command round trip (sealed ping → accepted CommandAck)")
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
