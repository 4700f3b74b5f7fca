"""`ato up --vehicles 2`: router, trackside and two onboard processes; liveliness when an onboard
is killed or frozen; a clean shutdown that leaves no process behind."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest
from prometheus_client.parser import text_string_to_metric_families
from typer.testing import CliRunner

from deploy.cli import app
from deploy.pki import Role, init_ca, issue
from onboard.freshness import Refusal
from onboard.track_store import TrackDataStore
from onboard.vc.datalog import read_datalog
from protocol import TlsFiles, TransportError, ZenohSettings, open_session, request
from protocol import messages as m
from protocol.registry import COMMAND
from tests.conftest import wait_for
from trackdb import Line, load_seed_line

pytestmark = pytest.mark.e2e

KILLED_NOT_ALIVE_S = 1.0
FROZEN_NOT_ALIVE_S = 1.5
"""CONTRACT: a killed onboard is not alive within 1 s; a frozen one (SIGSTOP) within 1.5 s."""


class Up:
    def __init__(self, process: subprocess.Popen[str], lines: list[str]) -> None:
        self.process = process
        text = "\n".join(lines)
        found = re.search(r"console (\S+)/ \(login (\S+) / (\S+)\)", text)
        assert found, text
        self.url, user, password = found.groups()
        router = re.search(r"router (\S+),", text)
        assert router, text
        self.router = router.group(1)
        self.pids = {
            name: int(pid) for name, pid in re.findall(r"^\s+(\S+)\s+pid (\d+)", text, re.MULTILINE)
        }
        self.metrics = dict(re.findall(r"^\s+metrics: (URV\d+) (\S+)$", text, re.MULTILINE))
        token = httpx.post(
            f"{self.url}/api/v1/auth/token", data={"username": user, "password": password}
        ).json()["access_token"]
        self.headers = {"Authorization": f"Bearer {token}"}

    def alive(self) -> dict[str, bool]:
        vehicles = httpx.get(f"{self.url}/api/v1/vehicles", headers=self.headers).json()
        return {item["id"]: item["alive"] for item in vehicles}


def _start(tmp_path: Path, *options: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "deploy",
            "up",
            "--vehicles",
            "2",
            "--port",
            "0",
            "--router-port",
            "0",
            "--data-dir",
            str(tmp_path),
            *options,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )


@contextmanager
def _running(process: subprocess.Popen[str]) -> Iterator[Up]:
    assert process.stdout is not None
    lines: list[str] = []
    for line in process.stdout:
        lines.append(line.rstrip())
        if line.startswith("  metrics: URV2"):
            break
        if "failed" in line:
            pytest.fail("\n".join(lines))
    try:
        yield Up(process, lines)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        process.stdout.close()


@pytest.fixture
def up(tmp_path: Path) -> Iterator[Up]:
    with _running(_start(tmp_path, "--speed", "5")) as fleet:
        yield fleet


def _time_until_not_alive(up: Up, vehicle: str, limit_s: float = 10.0) -> float:
    start = time.monotonic()
    while up.alive().get(vehicle, True):
        assert time.monotonic() - start < limit_s
        time.sleep(0.02)
    return time.monotonic() - start


def _running_pid(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_two_vehicles_come_up_die_freeze_and_shut_down_cleanly(up: Up) -> None:
    assert set(up.pids) == {"router", "trackside", "onboard-URV1", "onboard-URV2"}
    assert up.alive() == {"URV1": True, "URV2": True}

    os.kill(up.pids["onboard-URV2"], signal.SIGKILL)
    killed_s = _time_until_not_alive(up, "URV2")
    os.kill(up.pids["onboard-URV1"], signal.SIGSTOP)
    try:
        frozen_s = _time_until_not_alive(up, "URV1")
    finally:
        os.kill(up.pids["onboard-URV1"], signal.SIGCONT)
    assert killed_s <= KILLED_NOT_ALIVE_S, f"killed → not alive after {killed_s:.3f} s"
    assert frozen_s <= FROZEN_NOT_ALIVE_S, f"frozen → not alive after {frozen_s:.3f} s"
    assert wait_for(lambda: up.alive()["URV1"], 10.0)  # thawed: back

    up.process.send_signal(signal.SIGTERM)
    assert up.process.wait(30.0) == 0
    assert not [name for name, pid in up.pids.items() if _running_pid(pid)]


def _samples(text: str) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    return {
        (sample.name, tuple(sorted(sample.labels.items()))): sample.value
        for family in text_string_to_metric_families(text)
        for sample in family.samples
    }


def test_metrics_are_scraped_from_the_trackside_and_each_onboard(up: Up, tmp_path: Path) -> None:
    token = (tmp_path / "metrics-token").read_text().strip()
    assert httpx.get(f"{up.url}/metrics").status_code == 403  # the token is needed

    def trackside_metrics() -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
        scraped = httpx.get(f"{up.url}/metrics", headers={"Authorization": f"Bearer {token}"})
        assert scraped.status_code == 200, scraped.text
        return _samples(scraped.text)

    # The fleet is up when both vehicles are alive; their sessions follow within a report.
    assert wait_for(lambda: trackside_metrics()[("ato_ts_sessions_open", ())] == 2.0, 10.0)
    trackside = trackside_metrics()
    assert trackside[("ato_ts_vehicles_alive", ())] == 2.0
    for vehicle in ("URV1", "URV2"):
        assert trackside[("ato_ts_vehicle_alive", (("vehicle", vehicle),))] == 1.0
    assert set(up.metrics) == {"URV1", "URV2"}
    for vehicle, url in up.metrics.items():
        onboard = _samples(httpx.get(url).text)
        label = (("vehicle", vehicle),)
        assert onboard[("ato_ob_up", label)] == 1.0
        assert onboard[("ato_ob_session_established", label)] == 1.0
        assert onboard[("ato_ob_status_reports_sent_total", label)] > 0
        assert onboard[("ato_ob_position_confidence_m", label)] >= 0.0
        assert ("ato_ob_nmpc_solve_seconds_count", label) in onboard
        assert ("ato_ob_vc_events_total", (("kind", "eb_commanded"), *label)) in onboard
        assert onboard[("ato_ob_task_overruns_total", (("task", "control"), *label))] >= 0


def test_the_fleet_links_are_tls_and_only_its_own_parties_get_an_answer(
    up: Up, tmp_path: Path
) -> None:
    """Issue 20: no certificate, or one from another CA, opens no session; URV2's own
    certificate does, but a command it sends (to URV1 or to itself) gets no answer: the router
    does not let a vehicle query a command key. The control: the same bare ping from the
    trackside's certificate does reach URV1, which answers with its refusal (the ping is not
    sealed for the session URV1 holds with the trackside service)."""
    assert up.router.startswith("tls/"), up.router
    plain = ZenohSettings(mode="client", connect=(up.router.replace("tls/", "tcp/"),))
    with pytest.raises(TransportError), open_session(plain, connect_timeout_s=2.0):
        pass
    init_ca(tmp_path / "other")
    issue(tmp_path / "other", "URV1", Role.VEHICLE)
    forged = ZenohSettings(connect=(up.router,), tls=TlsFiles.of(tmp_path / "other", "URV1"))
    with pytest.raises(TransportError), open_session(forged, connect_timeout_s=2.0):
        pass
    urv2 = ZenohSettings(connect=(up.router,), tls=TlsFiles.of(tmp_path / "pki", "URV2"))
    with open_session(urv2, connect_timeout_s=5.0) as session:
        for vehicle in ("URV1", "URV2"):
            ping = m.Command(
                vehicle_id=vehicle, command_id=1, issued_by="intruder", body=m.PingCommand()
            )
            key = COMMAND.key(vehicle=vehicle)
            assert list(session.get(key, payload=COMMAND.encode(ping), timeout=2.0)) == []
    trackside = ZenohSettings(connect=(up.router,), tls=TlsFiles.of(tmp_path / "pki", "ts1"))
    ping = m.Command(vehicle_id="URV1", command_id=1, issued_by="test", body=m.PingCommand())
    with open_session(trackside, connect_timeout_s=5.0) as session:
        ack = request(session, COMMAND, ping, timeout_s=2.0, vehicle="URV1")
    assert (ack.accepted, ack.reason) == (False, Refusal.UNSEALED)


JOURNEY_WALL_S = 240.0
"""How long, in wall time, the two vehicles may take to drive their journeys at ×10."""


def _status(up: Up, vehicle: str) -> dict[str, object]:
    reply = httpx.get(f"{up.url}/api/v1/vehicles/{vehicle}", headers=up.headers).json()
    return dict(reply["status"] or {})


def _command(up: Up, vehicle: str, route: str, body: dict[str, object] | None = None) -> None:
    answer = httpx.post(
        f"{up.url}/api/v1/vehicles/{vehicle}/{route}",
        json=body or {},
        headers=up.headers,
        timeout=10.0,
    )
    assert answer.status_code == 200, answer.text
    assert answer.json()["accepted"], answer.text


def _until(up: Up, vehicle: str, check: object, what: str) -> dict[str, object]:
    deadline = time.monotonic() + JOURNEY_WALL_S
    while time.monotonic() < deadline:
        status = _status(up, vehicle)
        if status and check(status):  # type: ignore[operator]
            return status
        time.sleep(0.1)
    pytest.fail(f"{vehicle}: {what} not reached; last status {_status(up, vehicle)}")


def test_both_vehicles_are_driven_through_a_journey_over_rest(tmp_path: Path) -> None:
    with _running(_start(tmp_path, "--speed", "10", "--simulated-operators")) as up:
        vehicles = ("URV1", "URV2")
        for vehicle in vehicles:
            answer = httpx.post(f"{up.url}/api/v1/vehicles/{vehicle}/select", headers=up.headers)
            assert answer.status_code == 200, answer.text
            _until(up, vehicle, lambda s: not s["vital_control"]["eb_commanded"], "EB rearmed")
            _command(up, vehicle, "rd-target-speed", {"target_speed_kmh": 30.0})
        for vehicle in vehicles:
            _until(up, vehicle, lambda s: s["etcs_mode"] == "FS", "FS at the balise group")
            _command(up, vehicle, "rd-target-speed", {"target_speed_kmh": 0.0})
        for vehicle in vehicles:
            stopped = _until(up, vehicle, lambda s: s["speed_mps"] == 0.0, "standstill")
            journey = {
                "id": f"east-{vehicle.lower()}",
                "line_id": "bologna-ring",
                "start_position_m": stopped["position_m"],
                "max_speed_mps": 40 / 3.6,
                "timing_points": [
                    {
                        "id": "east",
                        "stopping_point_id": "east",
                        "arrival_time_s": 300.0,
                        "end_of_journey": True,
                    }
                ],
            }
            stored = httpx.post(f"{up.url}/api/v1/journeys", json=journey, headers=up.headers)
            assert stored.status_code == 201, stored.text
            sent = httpx.post(
                f"{up.url}/api/v1/vehicles/{vehicle}/journey-profile",
                json={"journey_id": journey["id"]},
                headers=up.headers,
                timeout=10.0,
            )
            assert sent.status_code == 200, sent.text
            assert sent.json()["accepted"], sent.text
        for vehicle in vehicles:
            _until(up, vehicle, lambda s: s["ato_state"] == "RE", "ready")
            _command(up, vehicle, "engage")
        for vehicle in vehicles:
            _until(up, vehicle, lambda s: s["ato_state"] == "EG", "engaged")
        for vehicle in vehicles:
            end = _until(
                up,
                vehicle,
                lambda s: s["ato_state"] == "NA" and s["speed_mps"] == 0.0,
                "end of journey",
            )
            assert abs(float(end["position_m"]) - 1975.0) <= 1.0  # type: ignore[arg-type]
        up.process.send_signal(signal.SIGTERM)
        assert up.process.wait(30.0) == 0
        assert not [name for name, pid in up.pids.items() if _running_pid(pid)]


def test_each_onboard_runs_a_two_board_vc_whose_datalog_replays(up: Up, tmp_path: Path) -> None:
    """`ato up`'s onboards fit the VC as on the seeds' vehicle: two boards in 2-out-of-2, with
    the datalog recorded under the data directory, which `ato vc replay` reads."""

    def replicas() -> object:
        vital = _status(up, "URV1").get("vital_control") or {}
        return vital.get("replicas") if isinstance(vital, dict) else None

    assert wait_for(lambda: replicas() == 2, 20.0)
    up.process.send_signal(signal.SIGTERM)
    assert up.process.wait(30.0) == 0
    for vehicle in ("URV1", "URV2"):
        datalog = tmp_path / "vc" / f"{vehicle}.jsonl"
        assert read_datalog(datalog).records, f"{vehicle}: nothing recorded"
        replay = CliRunner().invoke(app, ["vc", "replay", str(datalog)])
        assert replay.exit_code == 0, replay.output
        assert f"VC datalog {vehicle}.jsonl" in replay.output


def _import_into(database: str, line: Line, tmp_path: Path) -> None:
    """``ato trackdb import`` of ``line`` into ``database`` (made if it does not exist)."""
    file = tmp_path / f"{line.id}.json"
    file.write_text(line.model_dump_json(round_trip=True))
    result = CliRunner().invoke(app, ["trackdb", "import", str(file), "--database", database])
    assert result.exit_code == 0, result.output


def test_up_runs_its_vehicles_on_a_line_imported_into_its_database(tmp_path: Path) -> None:
    """Issue 21: ``ato up --line ID`` for a line of the user's own, imported beforehand; no
    line is built into the onboards: each gets it from the trackside and keeps a copy."""
    line = load_seed_line("bologna-ring").model_copy(update={"id": "my-ring", "name": "Mine"})
    _import_into(f"sqlite:///{(tmp_path / 'trackside.db').resolve()}", line, tmp_path)
    with _running(_start(tmp_path, "--line", "my-ring")) as up:
        for vehicle in ("URV1", "URV2"):
            status = _until(
                up, vehicle, lambda s: s["track_data_version"] == line.version(), "its line"
            )
            assert status["line_id"] == "my-ring"
            stored = TrackDataStore(tmp_path / "track" / vehicle).load("my-ring")
            assert stored is not None
            assert stored.version() == line.version()
        up.process.send_signal(signal.SIGTERM)
        assert up.process.wait(30.0) == 0


def test_up_refuses_a_line_its_trackside_does_not_hold(tmp_path: Path) -> None:
    process = _start(tmp_path, "--line", "nowhere")
    output, _ = process.communicate(timeout=120.0)
    assert process.returncode == 1, output
    assert "line nowhere is not stored at the trackside" in output
    assert "ato trackdb import" in output
