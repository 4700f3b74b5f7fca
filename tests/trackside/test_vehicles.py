"""Vehicles from liveliness and status, over REST and WebSocket."""

from __future__ import annotations

import pytest
import zenoh
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from protocol import TypedPublisher, declare_liveliness
from protocol import messages as m
from protocol.registry import STATUS
from tests.conftest import wait_for
from trackside.api.schemas import VehiclePublic
from trackside.bridge import VehicleSnapshot


def _status(vehicle: str, position_m: float) -> m.StatusReport:
    return m.StatusReport(
        vehicle_id=vehicle,
        seq=0,
        sim_time_s=1.0,
        line_id="bologna-ring",
        position_m=position_m,
        speed_mps=4.0,
        acceleration_mps2=0.1,
        traction_force_n=500.0,
        ato_state=m.AtoState.NOT_AVAILABLE,
        etcs_mode=m.EtcsMode.SR,
        sc_state=m.ScState.RD,
    )


def _vehicles(client: TestClient, headers: dict[str, str]) -> dict[str, dict[str, object]]:
    response = client.get("/api/v1/vehicles", headers=headers)
    assert response.status_code == 200
    return {item["id"]: item for item in response.json()}


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_vehicle_alive_with_status_then_not_alive(
    client: TestClient,
    admin_headers: dict[str, str],
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    _, onboard = zenoh_pair
    assert _vehicles(client, admin_headers) == {}
    token = declare_liveliness(onboard, "ato/alive/ob/URV7")
    with TypedPublisher(onboard, STATUS, vehicle="URV7") as publisher:

        def has_status() -> bool:
            publisher.put(_status("URV7", 123.5))
            return _vehicles(client, admin_headers).get("URV7", {}).get("status") is not None

        assert wait_for(has_status)
    item = _vehicles(client, admin_headers)["URV7"]
    assert item["alive"] is True
    status = item["status"]
    assert isinstance(status, dict)
    assert status["position_m"] == 123.5
    assert status["speed_mps"] == 4.0
    assert (status["ato_state"], status["etcs_mode"], status["sc_state"]) == ("NA", "SR", "RD")
    one = client.get("/api/v1/vehicles/URV7", headers=admin_headers).json()
    assert one["id"] == "URV7"

    token.undeclare()
    assert wait_for(lambda: _vehicles(client, admin_headers)["URV7"]["alive"] is False)
    assert _vehicles(client, admin_headers)["URV7"]["status"] is None


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_status_under_another_vehicles_key_is_not_shown(
    client: TestClient,
    admin_headers: dict[str, str],
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    _, onboard = zenoh_pair
    token = declare_liveliness(onboard, "ato/alive/ob/URV8")
    assert wait_for(lambda: "URV8" in _vehicles(client, admin_headers))
    with TypedPublisher(onboard, STATUS, vehicle="URV8") as publisher:
        publisher.put(_status("IMPOSTOR", 1.0))
        onboard.put("ato/ob/URV8/status", b"not json")
        assert wait_for(lambda: client.app.state.bridge.status_stats.bad_payloads >= 1)  # type: ignore[attr-defined]
    assert _vehicles(client, admin_headers)["URV8"]["status"] is None
    token.undeclare()


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_the_fleet_read_in_one_pass_is_each_vehicle_s_snapshot(
    client: TestClient,
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    """``ZenohBridge.fleet`` reads every vehicle at one instant under one lock each: the same
    as each vehicle's own snapshot but for the age, which grows between the two reads."""
    _, onboard = zenoh_pair
    bridge = client.app.state.bridge  # type: ignore[attr-defined]
    tokens = [declare_liveliness(onboard, f"ato/alive/ob/URV{n}") for n in (1, 2, 3)]
    assert wait_for(lambda: len(bridge.vehicle_ids()) == 3)
    with (
        TypedPublisher(onboard, STATUS, vehicle="URV1") as first,
        TypedPublisher(onboard, STATUS, vehicle="URV2") as second,
    ):
        for _ in range(3):
            first.put(_status("URV1", 5.0))
            second.put(_status("IMPOSTOR", 6.0))  # not shown under URV2
        assert wait_for(lambda: bridge.status_stats.received >= 6)
    tokens[2].undeclare()
    assert wait_for(lambda: not bridge.snapshot("URV3").alive)

    def without_age(snapshot: VehicleSnapshot) -> tuple[object, ...]:
        return (snapshot.id, snapshot.alive, snapshot.status, snapshot.status_rate_ok)

    fleet = bridge.fleet()
    assert [snapshot.id for snapshot in fleet] == ["URV1", "URV2", "URV3"]
    assert [without_age(s) for s in fleet] == [without_age(bridge.snapshot(s.id)) for s in fleet]
    assert fleet[0].status is not None
    assert fleet[0].status_age_s is not None
    assert (fleet[1].status, fleet[2].alive) == (None, False)
    for token in tokens[:2]:
        token.undeclare()


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_unknown_vehicle_is_404(client: TestClient, admin_headers: dict[str, str]) -> None:
    assert client.get("/api/v1/vehicles/NOPE", headers=admin_headers).status_code == 404


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_fleet_websocket_pushes_live_vehicles(
    client: TestClient,
    admin_headers: dict[str, str],
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    _, onboard = zenoh_pair
    token = declare_liveliness(onboard, "ato/alive/ob/URV5")
    bearer = admin_headers["Authorization"].split()[1]
    with (
        TypedPublisher(onboard, STATUS, vehicle="URV5") as publisher,
        client.websocket_connect("/api/v1/ws/fleet") as websocket,
    ):
        websocket.send_json({"type": "auth", "token": bearer})
        positions: list[float] = []
        for frame_index in range(40):
            publisher.put(_status("URV5", 10.0 * frame_index))
            frame = websocket.receive_json()
            assert frame["type"] == "fleet"
            vehicles = {v["id"]: v for v in frame["vehicles"]}
            if vehicles.get("URV5", {}).get("status"):
                positions.append(vehicles["URV5"]["status"]["position_m"])
            if len(set(positions)) >= 2:
                break
    assert len(set(positions)) >= 2, positions
    token.undeclare()


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_fleet_websocket_refuses_a_bad_token(client: TestClient) -> None:
    with client.websocket_connect("/api/v1/ws/fleet") as websocket:
        websocket.send_json({"type": "auth", "token": "wrong"})
        with pytest.raises(WebSocketDisconnect) as caught:
            websocket.receive_json()
    assert caught.value.code == 1008


def test_a_confirmation_of_no_known_kind_is_refused(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    answer = client.post(
        "/api/v1/vehicles/URV1/confirmations/eb-release", json={"number": 0}, headers=admin_headers
    )
    assert answer.status_code == 422
    assert "vigilance-ack" in answer.text  # the kinds there are


def test_the_energy_manager_s_figures_reach_the_console_s_status() -> None:
    energy = m.EnergyStatus(
        soc=0.4758,
        energy_to_go_j=4.3e6,
        energy_available_j=5.1e6,
        margin_j=0.8e6,
        range_extender_share=0.0,
        short=False,
        slowed=True,
    )
    report = _status("URV7", 10.0).model_copy(update={"energy": energy})
    snapshot = VehicleSnapshot("URV7", True, report, 0.1, True)
    public = VehiclePublic.from_snapshot(snapshot).model_dump(mode="json")
    assert public["status"]["energy"] == energy.model_dump(mode="json")
    older = VehiclePublic.from_snapshot(
        VehicleSnapshot("URV7", True, _status("URV7", 1.0), 0.1, True)
    )
    assert older.status is not None
    assert older.status.energy is None
