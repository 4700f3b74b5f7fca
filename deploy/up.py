"""``ato up --vehicles N``: a Zenoh router, the trackside and N onboard processes on one machine.

Each part is its own child process (``ato router``, ``ato trackside``, ``ato onboard``) with its
own log file under ``DATA_DIR/logs/``. The start is checked step by step: the router's port
accepts connections, the trackside answers ``/healthz``, then every vehicle shows as alive in
``GET /api/v1/vehicles``. SIGINT or SIGTERM stops the onboards, then the trackside, then the
router (SIGTERM, then SIGKILL after a grace period); the children also get SIGTERM from the
kernel if this process dies without cleaning up (``PR_SET_PDEATHSIG``), so nothing is orphaned.

The admin account comes from ``ATO_ADMIN_USER`` / ``ATO_ADMIN_PASSWORD`` when set; otherwise an
``admin`` account with a random password is created, printed, and written to
``DATA_DIR/admin-password`` (mode 0600). Many machines: see docs/deployment.md.
"""

from __future__ import annotations

import ctypes
import os
import secrets
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import httpx

from deploy.ports import free_tcp_port

__all__ = ["UpError", "UpPlan", "Fleet", "run_up"]

HEALTH_TIMEOUT_S = 60.0
STOP_GRACE_S = 5.0
_PR_SET_PDEATHSIG = 1


class UpError(RuntimeError):
    """A part did not come up."""


@dataclass(frozen=True)
class UpPlan:
    vehicles: int = 1
    line: str = "bologna-ring"
    host: str = "127.0.0.1"
    port: int = 8000
    """The trackside's HTTP port; 0 picks a free one."""
    router_port: int = 7447
    """The router's TCP port on loopback; 0 picks a free one."""
    data_dir: Path = Path(".ato/up")
    database: str | None = None
    """SQLAlchemy URL; a SQLite file in ``data_dir`` by default."""
    speed: float = 1.0
    fidelity: str = "point_mass"
    simulated_operators: bool = False
    """The trackside's simulated operator answers every vehicle's VC requests (unattended)."""

    def vehicle_ids(self) -> list[str]:
        return [f"URV{i}" for i in range(1, self.vehicles + 1)]


def _die_with_parent() -> None:
    """In the child, before exec: SIGTERM when the parent dies (Linux)."""
    try:
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except OSError:
        pass


@dataclass
class Part:
    name: str
    args: list[str]
    log_path: Path
    env: dict[str, str] | None = None
    process: subprocess.Popen[bytes] | None = None
    _log: IO[bytes] | None = None

    def start(self) -> None:
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        self._log = open(self.log_path, "ab")  # noqa: SIM115 - closed in stop()
        self.process = subprocess.Popen(
            self.args,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=self.env,
            preexec_fn=_die_with_parent if sys.platform == "linux" else None,
        )

    @property
    def pid(self) -> int | None:
        return None if self.process is None else self.process.pid

    @property
    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def terminate(self) -> None:
        if self.running:
            assert self.process is not None
            self.process.terminate()

    def wait(self, timeout_s: float) -> None:
        if self.process is None:
            return
        try:
            self.process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        if self._log is not None:
            self._log.close()
            self._log = None


def _ato(*args: str) -> list[str]:
    return [sys.executable, "-m", "deploy", *args]


@dataclass
class Fleet:
    """The parts of one ``ato up``, in start order."""

    plan: UpPlan
    router_endpoint: str
    url: str
    admin: tuple[str, str]
    parts: list[Part] = field(default_factory=list)
    _stop: threading.Event = field(default_factory=threading.Event)

    @classmethod
    def plan_parts(cls, plan: UpPlan) -> Fleet:
        router_port = plan.router_port or free_tcp_port()
        port = plan.port or free_tcp_port()
        endpoint = f"tcp/127.0.0.1:{router_port}"
        logs = plan.data_dir / "logs"
        user = os.environ.get("ATO_ADMIN_USER") or "admin"
        password = os.environ.get("ATO_ADMIN_PASSWORD") or secrets.token_urlsafe(12)
        env = dict(os.environ, ATO_ADMIN_USER=user, ATO_ADMIN_PASSWORD=password)
        if plan.simulated_operators:
            env["ATO_SIMULATED_OPERATORS"] = ",".join(plan.vehicle_ids())
        database = plan.database or f"sqlite:///{(plan.data_dir / 'trackside.db').resolve()}"
        fleet = cls(plan, endpoint, f"http://{plan.host}:{port}", (user, password))
        fleet.parts.append(
            Part("router", _ato("router", "--listen", endpoint), logs / "router.log")
        )
        fleet.parts.append(
            Part(
                "trackside",
                _ato(
                    "trackside",
                    "--host",
                    plan.host,
                    "--port",
                    str(port),
                    "--zenoh",
                    endpoint,
                    "--database",
                    database,
                ),
                logs / "trackside.log",
                env=env,
            )
        )
        for vehicle in plan.vehicle_ids():
            fleet.parts.append(
                Part(
                    f"onboard-{vehicle}",
                    _ato(
                        "onboard",
                        "--vehicle",
                        vehicle,
                        "--zenoh",
                        endpoint,
                        "--line",
                        plan.line,
                        "--speed",
                        str(plan.speed),
                        "--fidelity",
                        plan.fidelity,
                        "--vc-datalog",
                        str(plan.data_dir / "vc" / f"{vehicle}.jsonl"),
                    ),
                    logs / f"onboard-{vehicle}.log",
                )
            )
        return fleet

    def part(self, name: str) -> Part:
        for part in self.parts:
            if part.name == name:
                return part
        raise KeyError(name)

    # -- start and health ----------------------------------------------------------------------

    def start(
        self, *, timeout_s: float = HEALTH_TIMEOUT_S, stop: threading.Event | None = None
    ) -> None:
        """Start every part and wait until each is healthy; UpError (all stopped) if not, or
        if ``stop`` is set meanwhile."""
        self._stop = stop or threading.Event()
        try:
            router, trackside, *onboards = self.parts
            router.start()
            self._wait("router", router, self._router_listening, timeout_s)
            trackside.start()
            self._wait("trackside", trackside, self._trackside_healthy, timeout_s)
            for part in onboards:
                part.start()
            self._wait("vehicles", None, self._vehicles_alive, timeout_s)
        except BaseException:
            self.stop()
            raise

    def _wait(
        self, what: str, part: Part | None, healthy: Callable[[], bool], timeout_s: float
    ) -> None:
        deadline = time.monotonic() + timeout_s
        while not healthy():
            if self._stop.is_set():
                raise UpError(f"interrupted while waiting for the {what}")
            dead = [p for p in self.parts if p.process is not None and not p.running]
            if dead:
                raise UpError(
                    f"{dead[0].name} exited with {dead[0].process.returncode}"  # type: ignore[union-attr]
                    f" (see {dead[0].log_path})"
                )
            if time.monotonic() > deadline:
                where = f" (see {part.log_path})" if part is not None else ""
                raise UpError(f"{what} not healthy within {timeout_s:.0f} s{where}")
            time.sleep(0.1)

    def _router_listening(self) -> bool:
        port = int(self.router_endpoint.rsplit(":", 1)[1])
        with socket.socket() as probe:
            probe.settimeout(0.2)
            return probe.connect_ex(("127.0.0.1", port)) == 0

    def _trackside_healthy(self) -> bool:
        try:
            return httpx.get(f"{self.url}/healthz", timeout=1.0).status_code == 200
        except httpx.HTTPError:
            return False

    def token(self) -> str:
        user, password = self.admin
        answer = httpx.post(
            f"{self.url}/api/v1/auth/token",
            timeout=5.0,
            data={"username": user, "password": password},
        )
        answer.raise_for_status()
        return str(answer.json()["access_token"])

    def alive(self) -> dict[str, bool]:
        """Each vehicle the trackside knows, and whether it is alive."""
        answer = httpx.get(
            f"{self.url}/api/v1/vehicles",
            timeout=2.0,
            headers={"Authorization": f"Bearer {self.token()}"},
        )
        answer.raise_for_status()
        return {item["id"]: bool(item["alive"]) for item in answer.json()}

    def _vehicles_alive(self) -> bool:
        try:
            alive = self.alive()
        except httpx.HTTPError:
            return False
        return all(alive.get(v, False) for v in self.plan.vehicle_ids())

    # -- stop ----------------------------------------------------------------------------------

    def stop(self) -> None:
        """Onboards first, then the trackside, then the router."""
        for part in reversed(self.parts):
            part.terminate()
            part.wait(STOP_GRACE_S)

    def table(self) -> list[tuple[str, str, str]]:
        return [(p.name, str(p.pid), str(p.log_path)) for p in self.parts]


def run_up(plan: UpPlan, stop: threading.Event, *, out: Callable[[str], None] = print) -> int:
    """Bring the fleet up, report it, and run until ``stop``; the exit status."""
    plan.data_dir.mkdir(parents=True, exist_ok=True)
    fleet = Fleet.plan_parts(plan)
    if "ATO_ADMIN_PASSWORD" not in os.environ:
        secret = plan.data_dir / "admin-password"
        secret.write_text(fleet.admin[1] + "\n")
        secret.chmod(0o600)
    try:
        fleet.start(stop=stop)
    except UpError as exc:
        out(f"ato up failed: {exc}")
        return 1
    out(
        f"ato up: router {fleet.router_endpoint}, console {fleet.url}/ "
        f"(login {fleet.admin[0]} / {fleet.admin[1]})"
    )
    for name, pid, log in fleet.table():
        out(f"  {name:<16} pid {pid:<8} log {log}")
    reported: set[str] = set()
    try:
        while not stop.wait(0.5):
            for part in fleet.parts:
                if not part.running and part.name not in reported:
                    reported.add(part.name)
                    code = part.process.returncode if part.process else None
                    out(f"ato up: {part.name} exited ({code}); see {part.log_path}")
    finally:
        out("ato up: stopping")
        fleet.stop()
    return 0


def running_pids(parts: Sequence[Part]) -> list[int]:
    return [p.pid for p in parts if p.running and p.pid is not None]
