"""``ato up --vehicles N``: a Zenoh router, the trackside and N onboard processes on one machine.

``--line ID`` names any line the trackside's database holds: a built-in one (seeded at the
trackside's start) or one imported beforehand with ``ato trackdb import FILE --database URL``;
``ato up`` imports nothing itself, and refuses to start the onboards on a line the trackside
lacks. Each onboard gets its line from the trackside over Zenoh and keeps a verified copy in
``DATA_DIR/track/VEHICLE``.

Each part is its own child process (``ato router``, ``ato trackside``, ``ato onboard``) with its
own log file under ``DATA_DIR/logs/``. The start is checked step by step: the router's port
accepts connections, the trackside answers ``/healthz``, then every vehicle shows as alive in
``GET /api/v1/vehicles``. SIGINT or SIGTERM stops the onboards, then the trackside, then the
router (SIGTERM, then SIGKILL after a grace period); the children also get SIGTERM from the
kernel if this process dies without cleaning up (``PR_SET_PDEATHSIG``), so nothing is orphaned.

The admin account comes from ``ATO_ADMIN_USER`` / ``ATO_ADMIN_PASSWORD`` when set; otherwise an
``admin`` account with a random password is created, printed, and written to
``DATA_DIR/admin-password`` (mode 0600). The Zenoh links are TLS with mutual authentication and
the router's access control, with the certificates of ``DATA_DIR/pki`` (made on the first
start; ``--insecure`` for plain TCP, debugging only). Many machines: see docs/deployment.md.
The children are supervised by :class:`deploy.processes.ChildProcess`.
"""

from __future__ import annotations

import os
import secrets
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import httpx

from deploy.pki import deployment_pki
from deploy.ports import free_tcp_port
from deploy.processes import ChildError, ChildProcess, accepts_connections, ato_command, wait_ready

__all__ = ["UpError", "UpPlan", "Fleet", "run_up"]

TRACKSIDE_NAME = "ts1"
"""The trackside's instance id (``trackside.config.Settings.instance_id``'s default)."""
HEALTH_TIMEOUT_S = 60.0
STOP_GRACE_S = 5.0
LOGIN_TIMEOUT_S = 30.0
"""The longest wait for the admin's login [s] (a deliberately slow password hash, on a loaded
machine)."""


class UpError(ChildError):
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
    metrics: bool = True
    """Each onboard serves its Prometheus metrics on a free loopback port, the trackside at
    ``/metrics`` with a scrape token written to ``data_dir/metrics-token`` (docs/metrics.md)."""
    insecure: bool = False
    """Plain TCP links without certificates or access control (debugging only); by default the
    links are TLS with the certificates of ``data_dir/pki``, the router's ACL admitting the
    trackside ``ts1`` and the plan's vehicles (docs/security.md)."""

    @property
    def pki_dir(self) -> Path:
        return self.data_dir / "pki"

    def vehicle_ids(self) -> list[str]:
        return [f"URV{i}" for i in range(1, self.vehicles + 1)]


def _security_options(plan: UpPlan) -> list[str]:
    """``--pki DIR`` for every part, the plan's PKI made or completed; none when insecure."""
    if plan.insecure:
        return []
    pki = deployment_pki(plan.pki_dir, vehicles=plan.vehicle_ids(), tracksides=[TRACKSIDE_NAME])
    return ["--pki", str(pki)]


def _router_part(plan: UpPlan, endpoint: str, security: list[str], log: Path) -> ChildProcess:
    """The router, admitting the trackside and the plan's vehicles when secure."""
    admitted = [] if plan.insecure else ["--trackside", TRACKSIDE_NAME]
    admitted += [f"--vehicle={vehicle}" for vehicle in plan.vehicle_ids()]
    return _part("router", ato_command("router", "--listen", endpoint, *security, *admitted), log)


def _part(
    name: str, args: list[str], log_path: Path, env: dict[str, str] | None = None
) -> ChildProcess:
    """One child of the fleet: its output in its log, killed by the kernel if ``ato up`` dies."""
    return ChildProcess(
        args,
        name=name,
        env=env,
        log_file=log_path,
        die_with_parent=True,
        stop_timeout_s=STOP_GRACE_S,
    )


@dataclass
class Fleet:
    """The parts of one ``ato up``, in start order."""

    plan: UpPlan
    router_endpoint: str
    url: str
    admin: tuple[str, str]
    database: str = ""
    """The trackside's database URL."""
    metrics_token: str = field(default_factory=lambda: secrets.token_urlsafe(24))
    """The bearer token of the trackside's ``/metrics``."""
    metrics_urls: dict[str, str] = field(default_factory=dict)
    """Each onboard's metrics endpoint, by vehicle."""
    parts: list[ChildProcess] = field(default_factory=list)
    _stop: threading.Event = field(default_factory=threading.Event)
    _token: str | None = None

    @classmethod
    def plan_parts(cls, plan: UpPlan) -> Fleet:
        router_port = plan.router_port or free_tcp_port()
        port = plan.port or free_tcp_port()
        endpoint = f"{'tcp' if plan.insecure else 'tls'}/127.0.0.1:{router_port}"
        security = _security_options(plan)
        logs = plan.data_dir / "logs"
        user = os.environ.get("ATO_ADMIN_USER") or "admin"
        password = os.environ.get("ATO_ADMIN_PASSWORD") or secrets.token_urlsafe(12)
        env = dict(os.environ, ATO_ADMIN_USER=user, ATO_ADMIN_PASSWORD=password)
        metrics_token = os.environ.get("ATO_METRICS_TOKEN") or secrets.token_urlsafe(24)
        if plan.metrics:
            env["ATO_METRICS_TOKEN"] = metrics_token
        if plan.simulated_operators:
            env["ATO_SIMULATED_OPERATORS"] = ",".join(plan.vehicle_ids())
        database = plan.database or f"sqlite:///{(plan.data_dir / 'trackside.db').resolve()}"
        fleet = cls(plan, endpoint, f"http://{plan.host}:{port}", (user, password), database)
        fleet.metrics_token = metrics_token
        fleet.parts.append(_router_part(plan, endpoint, security, logs / "router.log"))
        fleet.parts.append(
            _part(
                "trackside",
                ato_command(
                    "trackside",
                    "--host",
                    plan.host,
                    "--port",
                    str(port),
                    "--zenoh",
                    endpoint,
                    "--database",
                    database,
                    *security,
                ),
                logs / "trackside.log",
                env=env,
            )
        )
        for vehicle in plan.vehicle_ids():
            fleet.parts.append(fleet._onboard_part(vehicle, security, logs))
        return fleet

    def _onboard_part(self, vehicle: str, security: list[str], logs: Path) -> ChildProcess:
        """``ato onboard`` for ``vehicle``, its metrics on a free loopback port if asked."""
        plan = self.plan
        metrics: list[str] = []
        if plan.metrics:
            metrics_port = free_tcp_port()
            metrics = ["--metrics-port", str(metrics_port)]
            self.metrics_urls[vehicle] = f"http://127.0.0.1:{metrics_port}/metrics"
        return _part(
            f"onboard-{vehicle}",
            ato_command(
                "onboard",
                "--vehicle",
                vehicle,
                "--zenoh",
                self.router_endpoint,
                "--line",
                plan.line,
                "--speed",
                str(plan.speed),
                "--track-dir",
                str(plan.data_dir / "track" / vehicle),
                "--fidelity",
                plan.fidelity,
                "--vc-datalog",
                str(plan.data_dir / "vc" / f"{vehicle}.jsonl"),
                *metrics,
                *security,
            ),
            logs / f"onboard-{vehicle}.log",
        )

    def part(self, name: str) -> ChildProcess:
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
            self._check_line()
            for part in onboards:
                part.start()
            self._wait("vehicles", None, self._vehicles_alive, timeout_s)
        except BaseException:
            self.stop()
            raise

    def _wait(
        self, what: str, part: ChildProcess | None, healthy: Callable[[], bool], timeout_s: float
    ) -> None:
        """Wait until ``healthy()``, while every started part keeps running."""
        log_file = part.log_file if part is not None else None
        try:
            wait_ready(
                what,
                healthy,
                children=self.parts,
                timeout_s=timeout_s,
                stop=self._stop,
                log_file=log_file,
            )
        except ChildError as exc:
            raise UpError(str(exc)) from exc

    def _router_listening(self) -> bool:
        return accepts_connections("127.0.0.1", int(self.router_endpoint.rsplit(":", 1)[1]))

    def _trackside_healthy(self) -> bool:
        try:
            return httpx.get(f"{self.url}/healthz", timeout=1.0).status_code == 200
        except httpx.HTTPError:
            return False

    def _check_line(self) -> None:
        """UpError unless the trackside holds the plan's line (the onboards get it there)."""
        line = self.plan.line
        try:
            answer = httpx.get(
                f"{self.url}/api/v1/lines/{line}/version",
                timeout=5.0,
                headers={"Authorization": f"Bearer {self.token()}"},
            )
        except httpx.HTTPError as exc:
            raise UpError(f"could not ask the trackside for line {line}: {exc}") from exc
        if answer.status_code == httpx.codes.NOT_FOUND:
            raise UpError(
                f"line {line} is not stored at the trackside: import it first "
                f"(ato trackdb import FILE --database {self.database})"
            )
        if answer.status_code != httpx.codes.OK:
            raise UpError(f"line {line}: the trackside answered {answer.status_code}")

    def token(self, *, fresh: bool = False) -> str:
        """The admin's bearer token, logged in once and kept (``fresh``: log in again). A login
        hashes the password on purpose slowly, which a trackside sharing two cores with tens of
        onboards answered in more than 5 s: polling liveness with a login each time made it
        worse, and the first request after the fleet came up timed out."""
        if self._token is None or fresh:
            user, password = self.admin
            answer = httpx.post(
                f"{self.url}/api/v1/auth/token",
                timeout=LOGIN_TIMEOUT_S,
                data={"username": user, "password": password},
            )
            answer.raise_for_status()
            self._token = str(answer.json()["access_token"])
        return self._token

    def alive(self) -> dict[str, bool]:
        """Each vehicle the trackside knows, and whether it is alive."""
        answer = self._vehicles()
        if answer.status_code == httpx.codes.UNAUTHORIZED:  # the kept token expired
            self.token(fresh=True)
            answer = self._vehicles()
        answer.raise_for_status()
        return {item["id"]: bool(item["alive"]) for item in answer.json()}

    def _vehicles(self) -> httpx.Response:
        return httpx.get(
            f"{self.url}/api/v1/vehicles",
            timeout=5.0,
            headers={"Authorization": f"Bearer {self.token()}"},
        )

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
            part.stop()

    def table(self) -> list[tuple[str, str, str]]:
        return [(p.name, str(p.pid), str(p.log_file)) for p in self.parts]


def run_up(plan: UpPlan, stop: threading.Event, *, out: Callable[[str], None] = print) -> int:
    """Bring the fleet up, report it, and run until ``stop``; the exit status."""
    plan.data_dir.mkdir(parents=True, exist_ok=True)
    fleet = Fleet.plan_parts(plan)
    if "ATO_ADMIN_PASSWORD" not in os.environ:
        secret = plan.data_dir / "admin-password"
        secret.write_text(fleet.admin[1] + "\n")
        secret.chmod(0o600)
    if plan.metrics and "ATO_METRICS_TOKEN" not in os.environ:
        token_file = plan.data_dir / "metrics-token"
        token_file.write_text(fleet.metrics_token + "\n")
        token_file.chmod(0o600)
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
    if plan.metrics:
        where = (
            "$ATO_METRICS_TOKEN"
            if "ATO_METRICS_TOKEN" in os.environ
            else plan.data_dir / "metrics-token"
        )
        out(f"  metrics: {fleet.url}/metrics (bearer token in {where})")
        for vehicle, url in fleet.metrics_urls.items():
            out(f"  metrics: {vehicle} {url}")
    reported: set[str] = set()
    try:
        while not stop.wait(0.5):
            for part in fleet.parts:
                if not part.running and part.name not in reported:
                    reported.add(part.name)
                    out(f"ato up: {part.name} exited ({part.returncode}); see {part.log_file}")
    finally:
        out("ato up: stopping")
        fleet.stop()
    return 0


def running_pids(parts: Sequence[ChildProcess]) -> list[int]:
    return [p.pid for p in parts if p.running and p.pid is not None]
