"""``ato bench up --vehicles N --drive K``: how many vehicles ``ato up`` holds on this machine.

It brings up a whole ``ato up`` fleet (router, trackside, N onboard processes, TLS links, the
trackside's simulated operator answering every VC) in real time or at ``--speed``, then drives
K of its vehicles through the field test's first leg over the remote driver's REST API, all at
once, as an operator at the console would: hold the vehicle, wait for the EB to be rearmed, RD
at 30 km/h in SR to the balise group that brings FS, stop, send a journey to the east platform,
engage ATO, and wait for the end of the journey at the platform. Meanwhile it samples every
part's CPU time and resident memory from ``/proc`` and each vehicle's liveness at the
trackside. It ends with SIGTERM to the fleet and checks that every process is gone.

What it prints: the time until every vehicle was alive; each driven vehicle's journey (wall
time, its stop's distance from the platform); vehicles seen not alive while the fleet ran;
CPU [% of one core] and memory [MB] of the onboards (median and max over the vehicles), the
trackside and the router; the clean shutdown. The run fails (exit 1) when a vehicle does not
come up, a journey does not end at the platform, a vehicle drops out, or a process is left.
"""

from __future__ import annotations

import os
import signal
import tempfile
import threading
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
from rich.console import Console
from rich.table import Table

from deploy.stats import percentiles
from deploy.up import Fleet, UpError, UpPlan, running_pids
from protocol.units import MPS_PER_KMH

__all__ = ["UpBenchResult", "bench_up", "print_up_bench"]

EAST_STOP_M = 1975.0
"""The ring's east platform [m]: the journey's end."""
ARRIVAL_S = 300.0
"""The journey's arrival at the east platform, from its start [s of simulated time]."""
STOP_TOLERANCE_M = 1.0
SAMPLE_PERIOD_S = 2.0
"""How often the parts' CPU and memory and the vehicles' liveness are sampled [s]."""
POLL_PERIOD_S = 0.5
MAX_REFUSALS = 5
_TICKS_PER_S = os.sysconf("SC_CLK_TCK")
_PAGE_BYTES = os.sysconf("SC_PAGE_SIZE")
_MB = 1024 * 1024


@dataclass
class Usage:
    """One process's CPU time and resident memory over the bench."""

    cpu_s: float = 0.0
    first_cpu_s: float | None = None
    first_at_s: float | None = None
    last_at_s: float | None = None
    rss_max_mb: float = 0.0

    def sample(self, cpu_s: float, rss_mb: float, at_s: float) -> None:
        if self.first_cpu_s is None:
            self.first_cpu_s, self.first_at_s = cpu_s, at_s
        self.cpu_s, self.last_at_s = cpu_s, at_s
        self.rss_max_mb = max(self.rss_max_mb, rss_mb)

    @property
    def cpu_percent(self) -> float | None:
        """Its mean CPU use between the first and the last sample [% of one core]."""
        if self.first_cpu_s is None or self.first_at_s is None or self.last_at_s is None:
            return None
        span = self.last_at_s - self.first_at_s
        return None if span <= 0.0 else 100.0 * (self.cpu_s - self.first_cpu_s) / span


@dataclass
class Journey:
    """One driven vehicle's way through the field test's first leg."""

    vehicle: str
    step: int = 0
    started_s: float = 0.0
    ended_s: float | None = None
    stop_error_m: float | None = None
    failure: str | None = None
    refusals: int = 0
    """Engage commands refused before one was accepted."""
    last_refusal: str | None = None


@dataclass
class UpBenchResult:
    vehicles: int
    driven: int
    speed: float
    up_s: float | None = None
    """From the start of the router until every vehicle was alive [s]."""
    failure: str | None = None
    journeys: list[Journey] = field(default_factory=list)
    not_alive: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    """Vehicles seen not alive while the fleet ran, and how many samples each."""
    usage: dict[str, Usage] = field(default_factory=lambda: defaultdict(Usage))
    """By part name (``router``, ``trackside``, ``onboard-URV1`` ...)."""
    clean_shutdown: bool = False
    exit_codes: dict[str, int | None] = field(default_factory=dict)
    left_behind: list[int] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return (
            self.failure is None
            and all(j.failure is None and j.ended_s is not None for j in self.journeys)
            and not self.not_alive
            and self.clean_shutdown
            and not self.left_behind
        )


def _proc_usage(pid: int) -> tuple[float, float] | None:
    """A process's CPU time [s] (user and system, its own) and resident memory [MB]."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        statm = Path(f"/proc/{pid}/statm").read_text()
    except OSError:
        return None
    fields = stat.rsplit(")", 1)[1].split()
    cpu_s = (int(fields[11]) + int(fields[12])) / _TICKS_PER_S
    return cpu_s, int(statm.split()[1]) * _PAGE_BYTES / _MB


class _Sampler:
    """Samples the fleet's processes and the vehicles' liveness in a thread."""

    def __init__(self, fleet: Fleet, result: UpBenchResult, alive: Callable[[], dict[str, bool]]):
        self.fleet, self.result, self.alive = fleet, result, alive
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="up-bench-sampler", daemon=True)

    def __enter__(self) -> _Sampler:
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        while True:
            self.sample()
            if self._stop.wait(SAMPLE_PERIOD_S):
                self.sample()
                return

    def sample(self) -> None:
        now = time.monotonic()
        for part in self.fleet.parts:
            if part.pid is None:
                continue
            usage = _proc_usage(part.pid)
            if usage is not None:
                self.result.usage[part.name].sample(*usage, now)
        try:
            alive = self.alive()
        except httpx.HTTPError:
            return
        for vehicle in self.fleet.plan.vehicle_ids():
            if not alive.get(vehicle, False):
                self.result.not_alive[vehicle] += 1


class _Operator:
    """The console's REST calls of one driver holding the driven vehicles."""

    def __init__(self, fleet: Fleet) -> None:
        self.url = fleet.url
        self.client = httpx.Client(timeout=10.0)
        self.headers = {"Authorization": f"Bearer {fleet.token()}"}

    def alive(self) -> dict[str, bool]:
        answer = self.client.get(f"{self.url}/api/v1/vehicles", headers=self.headers)
        answer.raise_for_status()
        return {item["id"]: bool(item["alive"]) for item in answer.json()}

    def status(self, vehicle: str) -> dict[str, Any]:
        answer = self.client.get(f"{self.url}/api/v1/vehicles/{vehicle}", headers=self.headers)
        answer.raise_for_status()
        return dict(answer.json()["status"] or {})

    def post(self, path: str, body: dict[str, Any] | None = None) -> httpx.Response:
        return self.client.post(f"{self.url}/api/v1/{path}", json=body, headers=self.headers)

    def command(self, vehicle: str, route: str, body: dict[str, Any] | None = None) -> str | None:
        """The command sent; None if the vehicle accepted it, else why not."""
        answer = self.post(f"vehicles/{vehicle}/{route}", body or {})
        if answer.status_code != httpx.codes.OK or not answer.json().get("accepted"):
            return f"{route}: {answer.status_code} {answer.text[:200]}"
        return None

    def send_journey(self, vehicle: str, position_m: float) -> str | None:
        journey = {
            "id": f"bench-east-{vehicle.lower()}-{time.monotonic_ns()}",
            "line_id": "bologna-ring",
            "start_position_m": position_m,
            "max_speed_mps": 40 * MPS_PER_KMH,
            "timing_points": [
                {
                    "id": "east",
                    "stopping_point_id": "east",
                    "arrival_time_s": ARRIVAL_S,
                    "end_of_journey": True,
                }
            ],
        }
        stored = self.post("journeys", journey)
        if stored.status_code != httpx.codes.CREATED:
            return f"journey not stored: {stored.status_code} {stored.text[:200]}"
        return self.command(vehicle, "journey-profile", {"journey_id": journey["id"]})


def _advance(operator: _Operator, journey: Journey, status: dict[str, Any]) -> None:
    """One look at a driven vehicle: the next step of its drive once the last one holds."""
    vehicle = journey.vehicle
    failure: str | None = None
    if journey.step == 0:
        answer = operator.post(f"vehicles/{vehicle}/select")
        if not answer.is_success:
            failure = f"select: {answer.status_code} {answer.text[:200]}"
        journey.step = 1
    elif journey.step == 1 and not status["vital_control"]["eb_commanded"]:
        failure = operator.command(vehicle, "rd-target-speed", {"target_speed_kmh": 30.0})
        journey.step = 2
    elif journey.step == 2 and status["etcs_mode"] == "FS":
        failure = operator.command(vehicle, "rd-target-speed", {"target_speed_kmh": 0.0})
        journey.step = 3
    elif journey.step == 3 and status["speed_mps"] == 0.0:
        failure = operator.send_journey(vehicle, float(status["position_m"]))
        journey.step = 4
    elif journey.step == 4 and status["ato_state"] == "RE":
        failure = operator.command(vehicle, "engage")
        if failure is not None and journey.refusals < MAX_REFUSALS:
            # Refused (the vehicle's state moved on since the status read): press again at
            # the next look, as a driver at the console would.
            journey.refusals += 1
            journey.last_refusal = failure
            return
        journey.step = 5
    elif journey.step == 5 and status["ato_state"] == "NA" and status["speed_mps"] == 0.0:
        journey.ended_s = time.monotonic() - journey.started_s
        journey.stop_error_m = float(status["position_m"]) - EAST_STOP_M
        if abs(journey.stop_error_m) > STOP_TOLERANCE_M:
            failure = f"ended {journey.stop_error_m:+.2f} m from the platform"
        journey.step = 6
    journey.failure = failure


def _drive(operator: _Operator, journeys: list[Journey], timeout_s: float) -> None:
    """Drive every journey to its end (or failure), all at once."""
    deadline = time.monotonic() + timeout_s
    for journey in journeys:
        journey.started_s = time.monotonic()
    while time.monotonic() < deadline:
        active = [j for j in journeys if j.failure is None and j.ended_s is None]
        if not active:
            return
        for journey in active:
            status = operator.status(journey.vehicle) if journey.step > 0 else {}
            if journey.step == 0 or status:
                _advance(operator, journey, status)
        time.sleep(POLL_PERIOD_S)
    for journey in journeys:
        if journey.failure is None and journey.ended_s is None:
            journey.failure = (
                f"not at the end of its journey within {timeout_s:.0f} s (step {journey.step})"
            )


@contextmanager
def _data_dir(data_dir: Path | None) -> Iterator[Path]:
    if data_dir is not None:
        data_dir.mkdir(parents=True, exist_ok=True)
        yield data_dir
        return
    with tempfile.TemporaryDirectory(prefix="ato-bench-up-") as scratch:
        yield Path(scratch)


def bench_up(
    *, vehicles: int, drive: int, speed: float = 1.0, data_dir: Path | None = None
) -> UpBenchResult:
    """Bring up ``vehicles`` vehicles, drive ``drive`` of them, measure, shut down."""
    result = UpBenchResult(vehicles=vehicles, driven=min(drive, vehicles), speed=speed)
    # At --speed X a journey of ~400 simulated seconds takes 400/X s of wall time; the rest is
    # the margin of a loaded machine.
    timeout_s = 3.0 * (ARRIVAL_S + 200.0) / speed + 120.0
    with _data_dir(data_dir) as where:
        plan = UpPlan(
            vehicles=vehicles,
            port=0,
            router_port=0,
            data_dir=where,
            speed=speed,
            simulated_operators=True,
        )
        fleet = Fleet.plan_parts(plan)
        started = time.monotonic()
        try:
            fleet.start(timeout_s=max(60.0, 3.0 * vehicles))
        except UpError as exc:
            result.failure = f"the fleet did not come up: {exc}"
            result.left_behind = running_pids(fleet.parts)
            return result
        result.up_s = time.monotonic() - started
        operator = None
        try:
            try:
                operator = _Operator(fleet)
            except httpx.HTTPError as exc:
                result.failure = f"the operator could not log in: {exc!r}"
                return result
            result.journeys = [Journey(v) for v in plan.vehicle_ids()[: result.driven]]
            with _Sampler(fleet, result, operator.alive):
                _drive(operator, result.journeys, timeout_s)
        finally:
            if operator is not None:
                operator.client.close()
            fleet.stop()
            result.left_behind = running_pids(fleet.parts)
            result.exit_codes = {p.name: p.returncode for p in fleet.parts}
            # Each part stops on SIGTERM (its own exit, or the signal's); none had to be killed.
            result.clean_shutdown = all(
                code in (0, -signal.SIGTERM) for code in result.exit_codes.values()
            )
    return result


def print_up_bench(result: UpBenchResult, console: Console) -> None:
    """The bench's table."""
    table = Table(
        title=f"ato up: {result.vehicles} vehicles, {result.driven} driven, "
        f"speed {result.speed:g}×: {'OK' if result.ok else 'FAILED'}"
    )
    table.add_column("figure")
    table.add_column("value")
    if result.failure is not None:
        table.add_row("failure", result.failure)
    if result.up_s is not None:
        table.add_row("every vehicle alive after", f"{result.up_s:.1f} s")
    ended = [j.ended_s for j in result.journeys if j.ended_s is not None]
    table.add_row("journeys ended at the platform", f"{len(ended)} of {len(result.journeys)}")
    if ended:
        figures = percentiles(ended, (50, 100))
        table.add_row("journey wall time p50 / max", f"{figures[0]:.0f} / {figures[1]:.0f} s")
    errors = [abs(j.stop_error_m) for j in result.journeys if j.stop_error_m is not None]
    if errors:
        table.add_row("|stop error| max", f"{max(errors):.3f} m")
    for journey in result.journeys:
        if journey.failure is not None:
            table.add_row(f"{journey.vehicle} failed", journey.failure)
        if journey.refusals:
            table.add_row(
                f"{journey.vehicle}: engage refused {journey.refusals}×", str(journey.last_refusal)
            )
    dropped = ", ".join(f"{v} ({n})" for v, n in sorted(result.not_alive.items())) or "none"
    table.add_row("vehicles seen not alive (samples)", dropped)
    onboards = [u for name, u in result.usage.items() if name.startswith("onboard-")]
    cpu = [u.cpu_percent for u in onboards if u.cpu_percent is not None]
    if cpu:
        median, top = percentiles(cpu, (50, 100))
        table.add_row("onboard CPU p50 / max", f"{median:.1f} / {top:.1f} % of a core")
        table.add_row("onboards' CPU in all", f"{sum(cpu) / 100.0:.2f} cores")
    if onboards:
        rss = [u.rss_max_mb for u in onboards]
        median, top = percentiles(rss, (50, 100))
        table.add_row("onboard memory p50 / max", f"{median:.0f} / {top:.0f} MB")
        table.add_row("onboards' memory in all", f"{sum(rss) / 1024:.1f} GiB")
    for name in ("trackside", "router"):
        usage = result.usage.get(name)
        if usage is not None and usage.cpu_percent is not None:
            table.add_row(
                name, f"CPU {usage.cpu_percent:.1f} % of a core, memory {usage.rss_max_mb:.0f} MB"
            )
    unclean = {name: code for name, code in result.exit_codes.items() if code != 0}
    table.add_row(
        "clean shutdown",
        ("yes" if result.clean_shutdown and not result.left_behind else "no")
        + (f" (exit codes {unclean})" if unclean else "")
        + (f" (left running: {result.left_behind})" if result.left_behind else ""),
    )
    console.print(table)
