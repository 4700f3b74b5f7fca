"""Running the parts: an onboard in this process, or any ``ato`` subcommand as a child."""

from __future__ import annotations

import logging
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import FrameType

from onboard.node import Fidelity, OnboardNode, OnboardSettings
from onboard.runtime import RealTimeClock
from protocol import ZenohSettings, open_session
from trackdb import TrackMap, load_seed_line

__all__ = ["ato_command", "child_process", "run_onboard", "stop_on_signals"]

_log = logging.getLogger(__name__)


def ato_command(*args: str) -> list[str]:
    """The command line of an ``ato`` subcommand run with this interpreter."""
    return [sys.executable, "-m", "deploy", *args]


@contextmanager
def child_process(
    args: Sequence[str], *, log_file: Path | None = None, stop_timeout_s: float = 5.0
) -> Iterator[subprocess.Popen[bytes]]:
    """Start a child for the ``with`` block; SIGTERM it (then SIGKILL) on exit."""
    log = open(log_file, "ab") if log_file is not None else None  # noqa: SIM115 - closed below
    process = subprocess.Popen(
        list(args), stdout=log or subprocess.DEVNULL, stderr=subprocess.STDOUT if log else None
    )
    try:
        yield process
    finally:
        if process.poll() is None:
            process.terminate()
            try:
                process.wait(stop_timeout_s)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        if log is not None:
            log.close()


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
) -> None:
    """Run one vehicle's onboard in real time × ``speed_factor`` until ``stop`` is set: the VC
    is two boards in 2-out-of-2 by default, recording its datalog at ``vc_datalog`` if given."""
    track_map = TrackMap(load_seed_line(line_id))
    if vc_datalog is not None:
        vc_datalog.parent.mkdir(parents=True, exist_ok=True)
    with open_session(zenoh) as session:
        node = OnboardNode(
            OnboardSettings(
                vehicle_id=vehicle_id,
                line_id=line_id,
                fidelity=fidelity,
                vc_replicas=vc_replicas,
                vc_datalog=vc_datalog,
            ),
            session=session,
            clock=RealTimeClock(speed_factor),
            track_map=track_map,
        )

        def stop_when_asked() -> None:
            stop.wait()
            node.stop()

        watcher = threading.Thread(target=stop_when_asked, daemon=True)
        watcher.start()
        _log.info("onboard %s running on %s at ×%g", vehicle_id, line_id, speed_factor)
        try:
            node.run()
        finally:
            node.close()
