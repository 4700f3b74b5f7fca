"""Track data to the vehicle, end to end: router + trackside service + onboard, all real.

The onboard starts with no copy of a line imported at the trackside (no line is built into
it): it fetches the line over Zenoh, checks it and stores it, then runs on it in lockstep. A new
version of the line is imported while the train runs under remote driving: the first transfer
is corrupted at the trackside's boundary (a wrong SHA-256) and refused; the next one is
verified and stored, the switch waits while the train moves, happens at standstill, and a
journey planned on the new version is then accepted.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh
from fastapi.testclient import TestClient

from deploy.processes import ChildProcess, ato_command
from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from onboard.track_store import TrackDataStore
from onboard.track_transfer import fetch_line
from protocol import TypedSubscriber, ZenohSettings, open_session
from protocol import messages as m
from protocol.registry import EVENT
from tests.conftest import wait_for
from tests.e2e.conftest import running_trackside
from tests.operator import LockstepOperator
from trackdb import Line, TrackMap, load_seed_line
from trackside.bridge import ZenohBridge

pytestmark = pytest.mark.e2e

LINE_ID = "my-ring"
FIRST = load_seed_line("bologna-ring").model_copy(update={"id": LINE_ID, "name": "My ring"})
SECOND = FIRST.model_copy(update={"name": "My ring, resurveyed"})
RD_SPEED_MPS = 30 / 3.6


def _import(client: TestClient, headers: dict[str, str], line: Line) -> None:
    response = client.post(
        "/api/v1/lines",
        content=line.model_dump_json(round_trip=True),
        headers=headers | {"Content-Type": "application/json"},
    )
    assert response.status_code == 201, response.text
    assert response.json()["version"] == line.version()


def _corrupting(bridge: ZenohBridge) -> Callable[[], None]:
    """The trackside's line documents altered in transit from now on (the version announced
    kept); the returned function ends it."""
    honest = bridge.line_document
    assert honest is not None

    def corrupted(line_id: str) -> tuple[str, str] | None:
        found = honest(line_id)
        if found is None:
            return None
        document, version = found
        return document.replace("resurveyed", "resurveyeD"), version

    bridge.line_document = corrupted

    def restore() -> None:
        bridge.line_document = honest

    return restore


class Onboard:
    """The node in lockstep, its events, and an operator's hands on the trackside's bridge."""

    def __init__(self, node: OnboardNode, operator: zenoh.Session, bridge: ZenohBridge) -> None:
        self.node = node
        self.events: list[m.Event] = []
        self._events = TypedSubscriber(
            operator, EVENT, on_message=lambda _k, e: self.events.append(e), vehicle="URV1"
        )
        self.hands = LockstepOperator(operator, node, trackside=bridge)

    def codes(self) -> list[str]:
        return [event.code for event in self.events]

    def run_until(self, condition: Callable[[], bool], limit_s: float) -> bool:
        return self.hands.run_until(condition, limit_s)

    def command(self, body: m.CommandBody) -> m.CommandAck:
        return self.hands.command(body)

    def answer_while(self, ask: Callable[[], Any]) -> Any:
        """``ask`` (a request the vehicle answers) made while the vehicle runs on a thread of
        its own, stopped once the answer is in."""
        answered = threading.Event()
        runner = threading.Thread(target=lambda: self.run_until(answered.is_set, 120.0))
        runner.start()
        try:
            return ask()
        finally:
            answered.set()
            runner.join()

    def close(self) -> None:
        self._events.close()


@pytest.fixture
def sessions(router_endpoint: str) -> Iterator[tuple[zenoh.Session, zenoh.Session]]:
    """The onboard's session and the test's own (events, nothing else) on the router."""
    settings = ZenohSettings(connect=(router_endpoint,))
    with open_session(settings) as onboard, open_session(settings) as operator:
        yield onboard, operator


def _journey(client: TestClient, headers: dict[str, str], start_m: float) -> dict[str, Any]:
    journey = {
        "id": "on-the-new-data",
        "line_id": LINE_ID,
        "start_position_m": start_m,
        "max_speed_mps": 40 / 3.6,
        "timing_points": [
            {"id": "east", "stopping_point_id": "east", "arrival_time_s": 300.0},
            {
                "id": "south",
                "stopping_point_id": "south",
                "arrival_time_s": 600.0,
                "end_of_journey": True,
            },
        ],
    }
    response = client.post("/api/v1/journeys", json=journey, headers=headers)
    assert response.status_code == 201, response.text
    return dict(response.json())


def test_the_onboard_gets_its_line_and_switches_to_a_new_version_at_standstill(
    router_endpoint: str, sessions: tuple[zenoh.Session, zenoh.Session], tmp_path: Path
) -> None:
    session, operator = sessions
    track_dir = tmp_path / "track"
    store = TrackDataStore(track_dir)
    with running_trackside(router_endpoint, tmp_path) as (client, headers):
        _import(client, headers, FIRST)
        bridge: ZenohBridge = client.app.state.bridge  # type: ignore[attr-defined]

        # No copy on board: the line comes from the trackside, checked and stored.
        assert store.load(LINE_ID) is None
        line = fetch_line(
            session, vehicle_id="URV1", line_id=LINE_ID, store=store, stop=threading.Event()
        )
        assert line.version() == FIRST.version()
        stored = store.load(LINE_ID)
        assert stored is not None
        assert stored.version() == FIRST.version()

        node = OnboardNode(
            OnboardSettings(
                vehicle_id="URV1", line_id=LINE_ID, vital_control=False, track_dir=track_dir
            ),
            session=session,
            clock=SimClock(),
            track_map=TrackMap(line),
        )
        onboard = Onboard(node, operator, bridge)
        try:
            _drive_switch_and_plan(onboard, client, headers, bridge, store)
        finally:
            onboard.close()
            node.close()


def _drive_switch_and_plan(
    onboard: Onboard,
    client: TestClient,
    headers: dict[str, str],
    bridge: ZenohBridge,
    store: TrackDataStore,
) -> None:
    node, database = onboard.node, onboard.node.track_database
    assert onboard.run_until(
        lambda: node.session_client.established and database.versions_match, 30.0
    )
    assert node.current_status().track_data_version == FIRST.version()

    # Remote driving: the train runs.
    assert onboard.command(m.RemoteDrivingTargetCommand(target_speed_mps=RD_SPEED_MPS)).accepted
    assert onboard.run_until(lambda: node.stack.speed_mps > 5.0, 60.0)

    # A new version at the trackside; its first transfer corrupted on the way: refused.
    restore = _corrupting(bridge)
    _import(client, headers, SECOND)
    assert onboard.run_until(lambda: "track_data.refused" in onboard.codes(), 30.0)
    refused = next(e for e in onboard.events if e.code == "track_data.refused")
    assert "SHA-256" in refused.text
    assert node.track_data.transfer.refused >= 1
    assert database.onboard_version == FIRST.version()
    assert "track_data.differ" in onboard.codes()

    # The next transfer is sound: received and stored, but the train moves: the switch waits.
    restore()
    assert onboard.run_until(lambda: "track_data.switch_deferred" in onboard.codes(), 30.0)
    assert "track_data.received" in onboard.codes()
    assert node.stack.speed_mps > 5.0
    assert database.onboard_version == FIRST.version()
    status = node.current_status()
    assert status.track_data_version == FIRST.version()
    assert status.track_data_pending == SECOND.version()
    stored = store.load(LINE_ID)
    assert stored is not None
    assert stored.version() == SECOND.version()

    # At standstill the onboard switches; its position is kept, the plant's world is not touched.
    assert onboard.command(m.RemoteDrivingTargetCommand(target_speed_mps=0.0)).accepted
    assert onboard.run_until(lambda: "track_data.switched" in onboard.codes(), 120.0)
    assert node.plant.speed_mps < 0.05
    assert (
        "track_data.switched" not in onboard.codes()[: onboard.codes().index("track_data.received")]
    )
    assert database.onboard_version == SECOND.version()
    assert node.stack.etcs.track_map is node.stack.track_map
    assert node.sensor_fusion.track_map is node.stack.track_map
    assert node.track_map.version == FIRST.version()  # the simulated world
    assert abs(node.stack.position_m - node.plant.position_m) < 20.0
    assert onboard.run_until(lambda: node.current_status().track_data_pending is None, 1.0)
    assert node.current_status().track_data_version == SECOND.version()

    # A journey planned on the new version is accepted.
    start_m = node.stack.track_map.normalise(node.plant.position_m)
    assert _journey(client, headers, start_m)["line_version"] == SECOND.version()
    assert client.post("/api/v1/vehicles/URV1/select", headers=headers).status_code == 200
    response = onboard.answer_while(
        lambda: client.post(
            "/api/v1/vehicles/URV1/journey-profile",
            json={"journey_id": "on-the-new-data"},
            headers=headers,
        )
    )
    assert response.status_code == 200, [(e.code, e.text) for e in onboard.events][-20:]
    assert response.json()["accepted"] is True
    assert database.journey is not None
    assert database.journey.track_data_version == SECOND.version()


def test_ato_onboard_waits_for_a_trackside_that_holds_its_line(
    router_endpoint: str, tmp_path: Path
) -> None:
    """``ato onboard --line ID`` with no copy and no trackside yet: it waits, then runs on the
    line once a trackside holds it, and keeps a verified copy."""
    track_dir = tmp_path / "track"
    args = ato_command(
        "onboard",
        *("--vehicle", "URV7", "--zenoh", router_endpoint, "--line", LINE_ID),
        *("--track-dir", str(track_dir), "--no-vc-datalog", "--speed", "2"),
    )
    log = tmp_path / "onboard.log"
    with ChildProcess(args, log_file=log) as onboard:
        assert wait_for(lambda: "no answer from a trackside" in _text(log), 30.0), _text(log)
        assert onboard.running
        assert TrackDataStore(track_dir).load(LINE_ID) is None
        with running_trackside(router_endpoint, tmp_path) as (client, headers):
            _import(client, headers, FIRST)

            def runs_on_the_line() -> bool:
                vehicles = client.get("/api/v1/vehicles", headers=headers).json()
                status = next((v["status"] for v in vehicles if v["id"] == "URV7"), None)
                if not status:
                    return False
                return bool(status["track_data_version"] == FIRST.version())

            assert wait_for(runs_on_the_line, 60.0), _text(log)
        stored = TrackDataStore(track_dir).load(LINE_ID)
        assert stored is not None
        assert stored.version() == FIRST.version()


def _text(path: Path) -> str:
    return path.read_text() if path.exists() else ""
