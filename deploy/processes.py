"""Running the parts: an onboard in this process, or any ``ato`` subcommand as a child.

:class:`ChildProcess` is the one supervisor of a child process, for ``ato up`` (its router,
trackside and onboards), ``ato demo`` (its onboard), the benches and the link proxy of the
``zenoh_link_loss`` fault: it starts the child with its command and environment, keeps its output
(appended to a log file, or on pipes for a line protocol), waits until it is ready (a line on its
standard output, a port that accepts connections, any check: :meth:`ChildProcess.wait_ready`) and
stops it (asked to stop, waited for, then killed), as a context manager.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import select
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import IO, TYPE_CHECKING, Self

from deploy._exceptions import DeployError

if TYPE_CHECKING:
    import zenoh

    from onboard.metrics import MetricsServer
    from onboard.node import Fidelity, OnboardNode
    from protocol import TlsFiles, ZenohSettings
    from trackdb import Line

__all__ = [
    "ChildError",
    "ChildProcess",
    "MetricsEndpoint",
    "accepts_connections",
    "ato_command",
    "run_onboard",
    "stop_on_signals",
    "wait_ready",
]

_log = logging.getLogger(__name__)

STOP_TIMEOUT_S = 5.0
"""How long a child asked to stop may take before it is killed [s]."""
READY_POLL_S = 0.1
"""How often a readiness check is repeated [s]."""
_PR_SET_PDEATHSIG = 1


class ChildError(DeployError, RuntimeError):
    """A child is not as asked: not started, or not ready (it exited, the wait for it timed out
    or was interrupted)."""


def ato_command(*args: str) -> list[str]:
    """The command line of an ``ato`` subcommand run with this interpreter."""
    return [sys.executable, "-m", "deploy", *args]


def _die_with_parent() -> None:
    """In the child, before exec: SIGTERM when the parent dies (Linux)."""
    try:
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except OSError:
        pass


def accepts_connections(host: str, port: int, *, timeout_s: float = 0.2) -> bool:
    """Whether a TCP connection to ``host:port`` is accepted now: a child that listens is up."""
    with socket.socket() as probe:
        probe.settimeout(timeout_s)
        return probe.connect_ex((host, port)) == 0


class ChildProcess:
    """One child process under supervision, from its start to its stop; a context manager.

    Parameters
    ----------
    args
        The command line.
    name
        What messages call the child (default: the command's first word).
    env
        Its environment (default: this process's).
    log_file
        Where its standard output and error are appended. Without it, its output is discarded
        and its errors go to this process's standard error.
    control
        Its standard input and output are pipes carrying one line per message
        (:meth:`send_line`, :meth:`read_line`) instead.
    stop_line
        With ``control``: the line that asks the child to stop, before its input is closed.
        Without it, :meth:`stop` asks with SIGTERM.
    die_with_parent
        Linux: the kernel sends the child SIGTERM when the thread that started it ends, so that
        nothing is orphaned if this process dies without cleaning up (``PR_SET_PDEATHSIG``). For
        a parent that starts its children from its main thread.
    stop_timeout_s
        How long :meth:`stop` waits for the child before it kills it [s].
    """

    def __init__(
        self,
        args: Sequence[str],
        *,
        name: str | None = None,
        env: Mapping[str, str] | None = None,
        log_file: Path | None = None,
        control: bool = False,
        stop_line: str | None = None,
        die_with_parent: bool = False,
        stop_timeout_s: float = STOP_TIMEOUT_S,
    ) -> None:
        self.args = list(args)
        self.name = name or Path(self.args[0]).name
        self.env = None if env is None else dict(env)
        self.log_file = log_file
        self.control = control
        self.stop_line = stop_line
        self.die_with_parent = die_with_parent
        self.stop_timeout_s = stop_timeout_s
        self._process: subprocess.Popen[bytes] | None = None
        self._log: IO[bytes] | None = None

    # -- life cycle ----------------------------------------------------------------------------

    def start(self) -> None:
        """Start the child (once; starting a started child does nothing)."""
        if self._process is not None:
            return
        if self.log_file is not None:
            self.log_file.parent.mkdir(parents=True, exist_ok=True)
            self._log = open(self.log_file, "ab")  # noqa: SIM115 - closed in stop()
        pipe = subprocess.PIPE if self.control else None
        try:
            self._process = subprocess.Popen(
                self.args,
                stdin=pipe or subprocess.DEVNULL,
                stdout=pipe or self._log or subprocess.DEVNULL,
                stderr=self._log if self.control else (subprocess.STDOUT if self._log else None),
                env=self.env,
                preexec_fn=_die_with_parent
                if self.die_with_parent and sys.platform == "linux"
                else None,
            )
        except BaseException:
            self._close_files()
            raise

    def stop(self) -> int | None:
        """Ask the child to stop, wait up to ``stop_timeout_s``, then kill it; its exit status
        (``None`` if it never started)."""
        process = self._process
        if process is None:
            return None
        if process.poll() is None:
            if self.control and self.stop_line is not None:
                with contextlib.suppress(OSError, ValueError):
                    self.send_line(self.stop_line)
                with contextlib.suppress(OSError):
                    assert process.stdin is not None
                    process.stdin.close()
            else:
                process.terminate()
            try:
                process.wait(self.stop_timeout_s)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        self._close_files()
        return process.returncode

    def _close_files(self) -> None:
        process = self._process
        for stream in (process.stdin, process.stdout) if process is not None else ():
            if stream is not None:
                with contextlib.suppress(OSError):
                    stream.close()
        if self._log is not None:
            self._log.close()
            self._log = None

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.stop()

    # -- state -----------------------------------------------------------------------------------

    @property
    def process(self) -> subprocess.Popen[bytes]:
        if self._process is None:
            raise ChildError(f"{self.name} is not started")
        return self._process

    @property
    def started(self) -> bool:
        return self._process is not None

    @property
    def pid(self) -> int | None:
        return None if self._process is None else self._process.pid

    @property
    def running(self) -> bool:
        return self._process is not None and self._process.poll() is None

    @property
    def returncode(self) -> int | None:
        return None if self._process is None else self._process.poll()

    # -- readiness and the line protocol ---------------------------------------------------------

    def wait_ready(
        self, ready: Callable[[], bool], *, timeout_s: float, stop: threading.Event | None = None
    ) -> None:
        """Wait until ``ready()`` holds; :class:`ChildError` if the child exits first, if
        ``timeout_s`` passes, or if ``stop`` is set meanwhile."""
        wait_ready(self.name, ready, children=(self,), timeout_s=timeout_s, stop=stop)

    def send_line(self, line: str) -> None:
        """Write one line to a ``control`` child's standard input."""
        stdin = self.process.stdin
        if stdin is None:
            raise ChildError(f"{self.name} has no control pipe")
        stdin.write(line.encode() + b"\n")
        stdin.flush()

    def read_line(self, timeout_s: float) -> str | None:
        """The next line of a ``control`` child's standard output, without its end of line;
        ``None`` if none came within ``timeout_s`` or the output ended."""
        stdout = self.process.stdout
        if stdout is None:
            raise ChildError(f"{self.name} has no control pipe")
        # One request, one answer line: nothing is ever left in the reader's buffer, so waiting
        # on the pipe itself is enough.
        ready, _, _ = select.select([stdout], [], [], timeout_s)
        line = stdout.readline() if ready else b""
        return line.decode().rstrip("\n") if line else None


def wait_ready(
    what: str,
    ready: Callable[[], bool],
    *,
    children: Sequence[ChildProcess],
    timeout_s: float,
    stop: threading.Event | None = None,
    log_file: Path | None = None,
) -> None:
    """Wait until ``ready()`` holds, while every started one of ``children`` keeps running.

    Raises :class:`ChildError` when one of them exits (naming its log), when ``timeout_s``
    passes (naming ``log_file``, or the only child's log), or when ``stop`` is set meanwhile.
    """
    interrupted = stop or threading.Event()
    deadline = time.monotonic() + timeout_s
    hint = log_file or (children[0].log_file if len(children) == 1 else None)
    while not ready():
        if interrupted.is_set():
            raise ChildError(f"interrupted while waiting for the {what}")
        dead = [child for child in children if child.started and not child.running]
        if dead:
            raise ChildError(
                f"{dead[0].name} exited with {dead[0].returncode} (see {dead[0].log_file})"
            )
        if time.monotonic() > deadline:
            where = f" (see {hint})" if hint is not None else ""
            raise ChildError(f"{what} not healthy within {timeout_s:.0f} s{where}")
        interrupted.wait(READY_POLL_S)


@contextmanager
def stop_on_signals(stop: threading.Event) -> Iterator[None]:
    """Set ``stop`` on SIGINT or SIGTERM for the ``with`` block (main thread only)."""

    def handler(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _line_to_run_on(
    session: zenoh.Session,
    vehicle_id: str,
    line_id: str,
    track_dir: Path | None,
    stop: threading.Event,
) -> Line | None:
    """The onboard's line: its copy, or the trackside's (``fetch_line``); None if ``stop`` came
    first."""
    from onboard import TrackDataUnavailableError
    from onboard.track_store import TrackDataStore
    from onboard.track_transfer import fetch_line

    store = None if track_dir is None else TrackDataStore(track_dir)
    _log.info("onboard %s: getting line %s (copies in %s)", vehicle_id, line_id, track_dir)
    try:
        return fetch_line(session, vehicle_id=vehicle_id, line_id=line_id, store=store, stop=stop)
    except TrackDataUnavailableError as exc:
        _log.warning("onboard %s stopped before it had its line: %s", vehicle_id, exc)
        return None


@dataclass(frozen=True)
class MetricsEndpoint:
    """Where an onboard process serves its metrics: ``port`` (0: a free one, logged) on
    ``addr``; HTTPS with client certificates of the deployment's CA when ``tls`` is given."""

    port: int
    addr: str = "127.0.0.1"
    tls: TlsFiles | None = None

    def serve(self, node: OnboardNode) -> MetricsServer:
        from onboard.metrics import OnboardCollector, serve_metrics

        server = serve_metrics(OnboardCollector(node), port=self.port, addr=self.addr, tls=self.tls)
        scheme = "http" if self.tls is None else "https"
        _log.info(
            "metrics of %s at %s://%s:%d/metrics", node.vehicle_id, scheme, self.addr, server.port
        )
        return server


def run_onboard(
    vehicle_id: str,
    *,
    zenoh: ZenohSettings,
    line_id: str,
    speed_factor: float,
    stop: threading.Event,
    fidelity: Fidelity = "point_mass",
    vc_replicas: int = 2,
    vc_datalog: Path | None = None,
    track_dir: Path | None = None,
    metrics: MetricsEndpoint | None = None,
) -> None:
    """Run one vehicle's onboard in real time × ``speed_factor`` until ``stop`` is set: the VC
    is two boards in 2-out-of-2 by default, recording its datalog at ``vc_datalog`` if given;
    its Prometheus metrics served at ``metrics`` if given (``onboard.metrics``).

    No line is built into the onboard: it starts on its copy in ``track_dir`` if the trackside
    holds no newer version, else on the trackside's line, fetched, verified and stored there;
    with neither it waits for a trackside that holds the line (``onboard.track_transfer``).
    The simulated vehicle's world is that line too."""
    # Imported here, not at the top: the supervisor above serves processes (the link proxy's
    # parent among them) that never run an onboard.
    from onboard.node import OnboardNode, OnboardSettings
    from onboard.runtime import RealTimeClock
    from protocol import open_session
    from trackdb import TrackMap

    if vc_datalog is not None:
        vc_datalog.parent.mkdir(parents=True, exist_ok=True)
    with open_session(zenoh) as session:
        line = _line_to_run_on(session, vehicle_id, line_id, track_dir, stop)
        if line is None:
            return
        node = OnboardNode(
            OnboardSettings(
                vehicle_id=vehicle_id,
                line_id=line_id,
                fidelity=fidelity,
                vc_replicas=vc_replicas,
                vc_datalog=vc_datalog,
                track_dir=track_dir,
            ),
            session=session,
            clock=RealTimeClock(speed_factor),
            track_map=TrackMap(line),
        )

        _log.info(
            "onboard %s running on %s %s at ×%g", vehicle_id, line_id, line.version(), speed_factor
        )
        _run_until_stopped(node, stop, metrics)


def _run_until_stopped(
    node: OnboardNode, stop: threading.Event, metrics: MetricsEndpoint | None
) -> None:
    """Run ``node`` (serving its metrics) until ``stop`` is set; close it."""

    def stop_when_asked() -> None:
        stop.wait()
        node.stop()

    watcher = threading.Thread(target=stop_when_asked, daemon=True)
    watcher.start()
    server = None if metrics is None else metrics.serve(node)
    try:
        node.run()
    finally:
        if server is not None:
            server.close()
        node.close()
