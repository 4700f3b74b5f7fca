"""``ato bench zenoh``: trackside→onboard command round trip over Zenoh.

Measures the time from the trackside sending a command query to it holding the onboard's
validated acknowledgement, with the real :class:`~onboard.node.OnboardNode` answering:

- in-process, peer to peer: both sessions in this process, one connected to the other;
- in-process, through a router: both sessions and a router in this process;
- across processes: ``ato router`` and ``ato onboard`` as child processes, the trackside here.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager

import zenoh
from rich.console import Console
from rich.table import Table

from deploy.ports import loopback_endpoint
from deploy.processes import ChildProcess, ato_command
from deploy.stats import percentiles
from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from protocol import (
    LivelinessWatcher,
    RequestTimeoutError,
    ZenohSettings,
    open_session,
    request,
)
from protocol import messages as m
from protocol.registry import ALIVE_ONBOARD, COMMAND
from protocol.router import run_router
from trackdb import TrackMap, load_seed_line

__all__ = ["bench_zenoh", "measure_round_trips"]

VEHICLE = "BENCH1"


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


@contextmanager
def _router(endpoint: str) -> Iterator[None]:
    stop, ready = threading.Event(), threading.Event()
    thread = threading.Thread(
        target=run_router, args=(stop,), kwargs={"listen": [endpoint], "ready": ready}, daemon=True
    )
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


def _in_process_peer(count: int, warmup: int) -> list[float]:
    endpoint = loopback_endpoint()
    with (
        open_session(ZenohSettings(mode="peer", connect=(), listen=(endpoint,))) as trackside,
        _onboard_in_process(ZenohSettings(mode="peer", connect=(endpoint,))),
    ):
        _wait_alive(trackside, 5.0)
        return measure_round_trips(trackside, count=count, warmup=warmup)


def _in_process_router(count: int, warmup: int) -> list[float]:
    endpoint = loopback_endpoint()
    with (
        _router(endpoint),
        open_session(ZenohSettings(connect=(endpoint,))) as trackside,
        _onboard_in_process(ZenohSettings(connect=(endpoint,))),
    ):
        _wait_alive(trackside, 5.0)
        return measure_round_trips(trackside, count=count, warmup=warmup)


def _across_processes(count: int, warmup: int) -> list[float]:
    endpoint = loopback_endpoint()
    with ExitStack() as stack:
        stack.enter_context(ChildProcess(ato_command("router", "--listen", endpoint)))
        stack.enter_context(
            ChildProcess(ato_command("onboard", "--vehicle", VEHICLE, "--zenoh", endpoint))
        )
        trackside = stack.enter_context(open_session(ZenohSettings(connect=(endpoint,))))
        _wait_alive(trackside, 30.0)
        return measure_round_trips(trackside, count=count, warmup=warmup)


def bench_zenoh(*, count: int, warmup: int) -> dict[str, dict[str, float]]:
    """Run the three measurements, print a table, return the figures [ms]."""
    console = Console(width=100)
    results: dict[str, dict[str, float]] = {}
    cases = {
        "in-process, peer to peer": _in_process_peer,
        "in-process, via router": _in_process_router,
        "across processes, via router": _across_processes,
    }
    for name, run in cases.items():
        console.print(f"measuring {name} ({count} commands)…")
        samples = run(count, warmup)
        median_s, p99_s, max_s = percentiles(samples, (50, 99, 100))
        results[name] = {
            "median_ms": median_s * 1e3,
            "p99_ms": p99_s * 1e3,
            "max_ms": max_s * 1e3,
            "count": float(len(samples)),
        }
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
    console.print("target: p99 ≤ 2 ms in-process")
    return results
