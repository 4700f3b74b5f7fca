"""Router + trackside + onboard, all real, in one process; then the CLI as child processes."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from deploy.processes import ChildProcess, ato_command
from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import RealTimeClock
from protocol import ZenohSettings, open_session
from tests.conftest import wait_for
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.e2e

VEHICLES = "/api/v1/vehicles"


def _vehicle(client: TestClient, headers: dict[str, str], vehicle: str) -> dict[str, object] | None:
    for item in client.get(VEHICLES, headers=headers).json():
        if item["id"] == vehicle:
            return dict(item)
    return None


def test_vehicle_appears_then_is_reported_gone(
    router_endpoint: str, trackside: tuple[TestClient, dict[str, str]]
) -> None:
    client, headers = trackside
    track_map = TrackMap(load_seed_line("bologna-ring"))
    with open_session(ZenohSettings(connect=(router_endpoint,))) as session:
        node = OnboardNode(
            OnboardSettings(vehicle_id="URV1"),
            session=session,
            clock=RealTimeClock(1.0),
            track_map=track_map,
        )
        runner = threading.Thread(target=node.run, daemon=True)
        started = time.monotonic()
        runner.start()
        assert wait_for(
            lambda: (_vehicle(client, headers, "URV1") or {}).get("status") is not None, 2.0
        )
        appeared_s = time.monotonic() - started
        item = _vehicle(client, headers, "URV1")
        assert item is not None
        assert item["alive"] is True
        # The onboard Track Database Manager asked the trackside for the line's version.
        assert wait_for(lambda: node.track_database.versions_match, 3.0)

        # Drive it as a control-room operator does: hold it, then command it through the
        # trackside, which seals each command for the session both sides hold.
        bridge = client.app.state.bridge  # type: ignore[attr-defined]
        assert wait_for(
            lambda: bridge.session_open("URV1") and node.session_client.established, 5.0
        )
        assert client.post(f"{VEHICLES}/URV1/select", headers=headers).status_code == 200
        answer = client.post(
            f"{VEHICLES}/URV1/rd-target-speed", json={"target_speed_kmh": 36.0}, headers=headers
        )
        assert answer.status_code == 200, answer.text
        assert answer.json()["accepted"], answer.json()["reason"]
        # The Vital Control holds the EB from power-up until the operator confirms its rearm:
        # the request reaches the trackside in the status, the confirmation goes back.
        assert wait_for(lambda: _rearm_request(client, headers) is not None, 3.0)
        answer = client.post(
            f"{VEHICLES}/URV1/confirmations/eb-rearm",
            json={"number": _rearm_request(client, headers)},
            headers=headers,
        )
        assert answer.status_code == 200, answer.text
        assert answer.json()["accepted"], answer.json()["reason"]
        assert wait_for(lambda: _speed(client, headers) > 0.1, 5.0)

        node.stop()
        runner.join(2.0)
        node.close()
        closed = time.monotonic()
    assert wait_for(lambda: (_vehicle(client, headers, "URV1") or {}).get("alive") is False, 2.0)
    gone_s = time.monotonic() - closed
    assert appeared_s < 2.0
    assert gone_s < 2.0


def _rearm_request(client: TestClient, headers: dict[str, str]) -> int | None:
    status = (_vehicle(client, headers, "URV1") or {}).get("status")
    vital = status.get("vital_control") if isinstance(status, dict) else None
    for pending in (vital or {}).get("operator_requests", []):
        if pending["kind"] == "eb_rearm":
            return int(pending["number"])
    return None


def _speed(client: TestClient, headers: dict[str, str]) -> float:
    item = _vehicle(client, headers, "URV1") or {}
    status = item.get("status")
    return float(status["speed_mps"]) if isinstance(status, dict) else 0.0


def test_cli_router_and_onboard_processes(
    trackside: tuple[TestClient, dict[str, str]], router_endpoint: str, tmp_path: Path
) -> None:
    """``ato onboard`` as a child process joins through the test's router; killing it is seen."""
    client, headers = trackside
    args = ato_command("onboard", "--vehicle", "URV2", "--zenoh", router_endpoint, "--speed", "2")
    with ChildProcess(args, log_file=tmp_path / "onboard.log") as onboard:
        process = onboard.process
        assert wait_for(
            lambda: (_vehicle(client, headers, "URV2") or {}).get("alive") is True, 30.0
        )
        process.terminate()
        process.wait(10.0)
        assert process.returncode == 0, (tmp_path / "onboard.log").read_text()
    assert wait_for(lambda: (_vehicle(client, headers, "URV2") or {}).get("alive") is False, 2.0)


def test_a_killed_process_is_noticed_within_the_lease(
    trackside: tuple[TestClient, dict[str, str]], router_endpoint: str, tmp_path: Path
) -> None:
    """SIGKILL leaves no time to withdraw the token: the ≤ 1 s link lease must notice."""
    client, headers = trackside
    args = ato_command("onboard", "--vehicle", "URV3", "--zenoh", router_endpoint)
    with ChildProcess(args, log_file=tmp_path / "onboard.log") as onboard:
        process = onboard.process
        assert wait_for(
            lambda: (_vehicle(client, headers, "URV3") or {}).get("alive") is True, 30.0
        )
        process.kill()
        process.wait(10.0)
        killed = time.monotonic()
        assert wait_for(
            lambda: (_vehicle(client, headers, "URV3") or {}).get("alive") is False, 3.0
        )
        assert time.monotonic() - killed < 2.0
