"""Journeys over REST: validate, create with versions, list, read; on SQLite and PostgreSQL."""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient

from tests.trackside.conftest import login

CAP_40_KMH = 40 / 3.6


def _journey(east_arrival_s: float = 300.0, journey_id: str = "field-test-lap") -> dict[str, Any]:
    return {
        "id": journey_id,
        "line_id": "bologna-ring",
        "start_position_m": 200.0,
        "max_speed_mps": CAP_40_KMH,
        "timing_points": [
            {
                "id": "east",
                "stopping_point_id": "east",
                "arrival_time_s": east_arrival_s,
                "minimum_dwell_s": 20.0,
            },
            {"id": "south", "stopping_point_id": "south", "arrival_time_s": east_arrival_s + 250},
            {
                "id": "north",
                "stopping_point_id": "north",
                "arrival_time_s": east_arrival_s + 700,
                "end_of_journey": True,
            },
        ],
    }


def test_validate_a_feasible_and_an_impossible_journey(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    good = client.post("/api/v1/journeys/validate", json=_journey(), headers=admin_headers)
    assert good.status_code == 200, good.text
    body = good.json()
    assert body["valid"] is True
    assert body["problems"] == []
    assert [leg["to_id"] for leg in body["legs"]] == ["east", "south", "north"]
    assert len(body["line_version"]) == 64

    bad = client.post("/api/v1/journeys/validate", json=_journey(60.0), headers=admin_headers)
    body = bad.json()
    assert body["valid"] is False
    assert "leg 0 (start → east" in body["problems"][0]
    assert body["legs"][0]["shortfall_s"] > 0


def test_create_versions_list_and_read(client: TestClient, admin_headers: dict[str, str]) -> None:
    first = client.post("/api/v1/journeys", json=_journey(), headers=admin_headers)
    assert first.status_code == 201, first.text
    assert first.json()["version"] == 1
    second = client.post("/api/v1/journeys", json=_journey(320.0), headers=admin_headers)
    assert second.json()["version"] == 2
    listed = client.get("/api/v1/journeys", headers=admin_headers).json()
    assert [(j["journey"]["id"], j["version"]) for j in listed] == [("field-test-lap", 2)]
    latest = client.get("/api/v1/journeys/field-test-lap", headers=admin_headers).json()
    assert latest["journey"]["timing_points"][0]["arrival_time_s"] == 320.0
    old = client.get("/api/v1/journeys/field-test-lap?version=1", headers=admin_headers).json()
    assert old["journey"]["timing_points"][0]["arrival_time_s"] == 300.0
    assert client.get("/api/v1/journeys/nope", headers=admin_headers).status_code == 404


def test_an_invalid_journey_is_refused_and_not_stored(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    response = client.post("/api/v1/journeys", json=_journey(60.0), headers=admin_headers)
    assert response.status_code == 422
    assert "shortfall" not in response.json()["detail"]["problems"][0]
    assert "by " in response.json()["detail"]["problems"][0]
    assert client.get("/api/v1/journeys", headers=admin_headers).json() == []


def test_bad_bodies_unknown_lines_and_roles(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    assert (
        client.post("/api/v1/journeys", json={"id": "x"}, headers=admin_headers).status_code == 422
    )
    other = _journey() | {"line_id": "atlantis"}
    assert (
        client.post("/api/v1/journeys/validate", json=other, headers=admin_headers).status_code
        == 404
    )
    client.post(
        "/api/v1/users",
        headers=admin_headers,
        json={"username": "watcher", "password": "observer-pw", "role": "observer"},
    )
    observer = login(client, "watcher", "observer-pw")
    assert client.post("/api/v1/journeys", json=_journey(), headers=observer).status_code == 403
    assert (
        client.post("/api/v1/journeys/validate", json=_journey(), headers=observer).status_code
        == 200
    )
    assert client.get("/api/v1/journeys").status_code == 401
