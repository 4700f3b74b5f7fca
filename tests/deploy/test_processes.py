"""The one child-process supervisor: start, readiness, output, stop (terminate, wait, kill)."""

from __future__ import annotations

import signal
import sys
import threading
from pathlib import Path

import pytest

from deploy.ports import free_tcp_port
from deploy.processes import ChildError, ChildProcess, accepts_connections, wait_ready

ECHO = """
import sys
print("ready", flush=True)
for line in sys.stdin:
    if line.strip() == "bye":
        sys.exit(3)
    print(line.strip().upper(), flush=True)
"""
STUBBORN = """
import signal, sys, time
signal.signal(signal.SIGTERM, signal.SIG_IGN)
print("ready", flush=True)
while True:
    time.sleep(1)
"""
LISTENER = """
import socket, sys, time
server = socket.create_server(("127.0.0.1", int(sys.argv[1])))
time.sleep(60)
"""


def _python(script: str, *args: str) -> list[str]:
    return [sys.executable, "-c", script, *args]


def test_a_control_child_says_it_is_ready_answers_and_stops_when_asked() -> None:
    child = ChildProcess(_python(ECHO), name="echo", control=True, stop_line="bye")
    with child:
        assert child.read_line(10.0) == "ready"
        child.send_line("hello")
        assert child.read_line(10.0) == "HELLO"
        assert child.running
    assert not child.running
    assert child.returncode == 3  # it left on the stop line, not on a signal


def test_a_child_deaf_to_sigterm_is_killed_after_the_timeout() -> None:
    child = ChildProcess(_python(STUBBORN), control=True, stop_timeout_s=0.5)
    child.start()
    assert child.read_line(10.0) == "ready"
    assert child.stop() == -signal.SIGKILL


def test_a_child_stops_on_sigterm_and_its_output_goes_to_its_log(tmp_path: Path) -> None:
    log = tmp_path / "logs" / "child.log"
    script = "import os, sys; print(os.environ['ATO_TEST'], flush=True); sys.exit('oops')"
    with ChildProcess(_python(script), env={"ATO_TEST": "value"}, log_file=log) as child:
        child.process.wait(10.0)
    assert child.returncode == 1
    assert log.read_text().split() == ["value", "oops"]
    sleeper = ChildProcess(_python("import time; time.sleep(60)"))
    with sleeper:
        assert sleeper.running
    assert sleeper.returncode == -signal.SIGTERM


def test_readiness_by_port(tmp_path: Path) -> None:
    port = free_tcp_port()
    child = ChildProcess(_python(LISTENER, str(port)), name="listener", log_file=tmp_path / "l")
    with child:
        child.wait_ready(lambda: accepts_connections("127.0.0.1", port), timeout_s=30.0)
    assert not accepts_connections("127.0.0.1", port)


def test_a_child_that_exits_or_never_gets_ready_is_an_error(tmp_path: Path) -> None:
    log = tmp_path / "dead.log"
    dead = ChildProcess(_python("raise SystemExit(4)"), name="dead", log_file=log)
    with dead, pytest.raises(ChildError, match=r"dead exited with 4 \(see .*dead.log\)"):
        dead.wait_ready(lambda: False, timeout_s=30.0)
    with ChildProcess(_python("import time; time.sleep(60)"), name="slow", log_file=log) as slow:
        with pytest.raises(ChildError, match=r"slow not healthy within 0 s \(see .*dead.log\)"):
            slow.wait_ready(lambda: False, timeout_s=0.2)
        stop = threading.Event()
        stop.set()
        with pytest.raises(ChildError, match="interrupted while waiting for the fleet"):
            wait_ready("fleet", lambda: False, children=[slow], timeout_s=30.0, stop=stop)


def test_a_child_not_started_has_no_process() -> None:
    child = ChildProcess(_python("pass"), name="idle")
    assert (child.started, child.pid, child.running, child.stop()) == (False, None, False, None)
    with pytest.raises(ChildError, match="idle is not started"):
        _ = child.process
