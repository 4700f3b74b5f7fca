"""The RBC over REST (roles, validation, refusals) and over Zenoh (ordered MAs, the queryable)."""

from __future__ import annotations

from typing import Any

import pytest
import zenoh
from fastapi.testclient import TestClient

from protocol import TypedPublisher, TypedSubscriber, declare_liveliness, request
from protocol import messages as m
from protocol.registry import (
    MOVEMENT_AUTHORITY,
    MOVEMENT_AUTHORITY_ACK,
    MOVEMENT_AUTHORITY_CURRENT,
    STATUS,
)
from protocol.units import MPS_PER_KMH
from tests.conftest import wait_for
from tests.trackside.conftest import login

pytestmark = pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)

MA = "/api/v1/rbc/URV1/ma"
ISSUE: dict[str, Any] = {"line_id": "bologna-ring", "start_m": 100.0, "end_of_authority_m": 900.0}


def _status(position_m: float) -> m.StatusReport:
    return m.StatusReport(
        vehicle_id="URV1",
        seq=0,
        sim_time_s=1.0,
        line_id="bologna-ring",
        position_m=position_m,
        speed_mps=4.0,
        acceleration_mps2=0.0,
        traction_force_n=0.0,
        ato_state=m.AtoState.ENGAGED,
        etcs_mode=m.EtcsMode.FS,
        sc_state=m.ScState.AD,
    )


def _current(onboard: zenoh.Session) -> m.MovementAuthorityReply:
    reply: m.MovementAuthorityReply = request(
        onboard,
        MOVEMENT_AUTHORITY_CURRENT,
        m.MovementAuthorityRequest(vehicle_id="URV1"),
        vehicle="URV1",
    )
    return reply


def test_subscriber_gets_every_change_in_order_and_the_queryable_the_current_one(
    client: TestClient,
    admin_headers: dict[str, str],
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    _, onboard = zenoh_pair
    received: list[m.MovementAuthorityMessage] = []
    with TypedSubscriber(
        onboard, MOVEMENT_AUTHORITY, on_message=lambda _key, ma: received.append(ma), vehicle="URV1"
    ):
        # A new subscription takes a moment to reach the publisher: issue until one arrives.
        assert wait_for(
            lambda: (client.post(MA, json=ISSUE, headers=admin_headers), bool(received))[1]
        )
        first = client.post(MA, json=ISSUE | {"overlap_m": 40.0}, headers=admin_headers)
        assert first.status_code == 201, first.text
        extended = client.post(
            f"{MA}/extend", json={"end_of_authority_m": 1500.0}, headers=admin_headers
        )
        assert extended.status_code == 200, extended.text
        shortened = client.post(
            f"{MA}/shorten", json={"end_of_authority_m": 1200.0}, headers=admin_headers
        )
        assert shortened.status_code == 200, shortened.text
        sent = [r.json()["movement_authority"] for r in (first, extended, shortened)]
        assert wait_for(lambda: bool(received) and received[-1].ma_id == sent[-1]["ma_id"])

        ids = [ma.ma_id for ma in received]
        assert ids == list(range(ids[0], ids[0] + len(ids)))
        tail = [ma.model_dump(mode="json") for ma in received[-3:]]
        assert tail == sent
        assert [ma.change for ma in received[-3:]] == ["issued", "extended", "shortened"]
        assert received[-3].authority is not None
        assert received[-3].authority.supervised_location_m == 940.0
        assert len(received[-1].line_version) == 64  # the stored line's current version

        assert _current(onboard).movement_authority == received[-1]

        revoked = client.delete(MA, headers=admin_headers)
        assert revoked.status_code == 200, revoked.text
        assert revoked.json()["supervised_location_m"] is None
        assert wait_for(lambda: received[-1].change is m.MovementAuthorityChange.REVOKED)
    assert _current(onboard) == m.MovementAuthorityReply(vehicle_id="URV1")
    assert client.get(MA, headers=admin_headers).status_code == 404


def test_read_shows_the_latest_acknowledgement(
    client: TestClient,
    admin_headers: dict[str, str],
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    _, onboard = zenoh_pair
    issued = client.post(MA, json=ISSUE, headers=admin_headers).json()["movement_authority"]
    ack = m.MovementAuthorityAck(
        vehicle_id="URV1", ma_id=issued["ma_id"], accepted=True, sim_time_s=2.0
    )
    with TypedPublisher(onboard, MOVEMENT_AUTHORITY_ACK, vehicle="URV1") as publisher:

        def acknowledged() -> bool:
            publisher.put(ack)
            return client.get(MA, headers=admin_headers).json()["acknowledgement"] is not None

        assert wait_for(acknowledged)
    body = client.get(MA, headers=admin_headers).json()
    assert body["acknowledgement"] == ack.model_dump(mode="json")
    assert body["movement_authority"] == issued
    assert body["supervised_location_m"] == 900.0


def test_shortening_behind_the_reported_front_end_is_refused(
    client: TestClient,
    admin_headers: dict[str, str],
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    _, onboard = zenoh_pair
    token = declare_liveliness(onboard, "ato/alive/ob/URV1")
    issued = client.post(MA, json=ISSUE | {"end_of_authority_m": 1500.0}, headers=admin_headers)
    assert issued.status_code == 201
    with TypedPublisher(onboard, STATUS, vehicle="URV1") as publisher:
        # Wait until the service holds the report; a shortening tried before it arrives would
        # be granted and change the authority this test goes on to check.
        def reported() -> bool:
            publisher.put(_status(700.0))
            status = client.get("/api/v1/vehicles/URV1", headers=admin_headers).json()["status"]
            return status is not None and status["position_m"] == 700.0

        assert wait_for(reported)
        behind = {"end_of_authority_m": 650.0}
        assert client.post(f"{MA}/shorten", json=behind, headers=admin_headers).status_code == 409
    response = client.post(
        f"{MA}/shorten", json={"end_of_authority_m": 700.0}, headers=admin_headers
    )
    assert response.status_code == 409
    message = response.json()["detail"]["message"]
    assert "700 m would lie at or behind URV1's front end, last reported at 700 m" in message
    current = client.get(MA, headers=admin_headers).json()["movement_authority"]
    assert current == issued.json()["movement_authority"]
    ok = client.post(f"{MA}/shorten", json={"end_of_authority_m": 800.0}, headers=admin_headers)
    assert ok.status_code == 200
    assert ok.json()["movement_authority"]["ma_id"] == current["ma_id"] + 1
    token.undeclare()


BAD_BODIES: list[tuple[dict[str, Any], str]] = [
    ({"start_m": 100.0, "end_of_authority_m": 900.0}, "line_id"),
    (ISSUE | {"end_of_authority_m": 50.0}, "must lie beyond the start"),
    (ISSUE | {"end_of_authority_m": "far"}, "end_of_authority_m"),
    (ISSUE | {"danger_point_m": -3.0}, "greater than or equal to 0"),
    (ISSUE | {"overlap_timer_s": 10.0}, "needs an overlap"),
    (ISSUE | {"eoa": 3.0}, "Extra inputs are not permitted"),
    (ISSUE | {"sections": [{"length_m": 100.0}]}, "sections add up to 100.0 m"),
]
UNSENDABLE: list[tuple[dict[str, Any], str]] = [
    (ISSUE | {"line_id": "atlantis"}, "the trackside holds no line 'atlantis'"),
    (ISSUE | {"line_version": "0" * 64}, "bologna-ring' is at version"),
    (ISSUE | {"end_of_authority_m": 6000.0}, "less than one lap"),
]


def test_bad_issues_are_422_with_the_reason_and_change_nothing(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    for body, needle in BAD_BODIES:
        response = client.post(MA, json=body, headers=admin_headers)
        assert response.status_code == 422, body
        assert needle in response.text, response.text
    for body, needle in UNSENDABLE:
        response = client.post(MA, json=body, headers=admin_headers)
        assert response.status_code == 422, body
        detail = response.json()["detail"]
        assert needle in detail["message"]
        assert detail["problems"] == [detail["message"]]
    assert client.get(MA, headers=admin_headers).status_code == 404


def test_changes_need_an_authority_and_the_right_direction(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    for path, method in ((f"{MA}/extend", "post"), (f"{MA}/shorten", "post"), (MA, "delete")):
        kwargs: dict[str, Any] = {"json": {"end_of_authority_m": 500.0}} if method == "post" else {}
        response = client.request(method.upper(), path, headers=admin_headers, **kwargs)
        assert response.status_code == 404, path
    assert client.post(MA, json=ISSUE, headers=admin_headers).status_code == 201
    backwards = client.post(
        f"{MA}/extend", json={"end_of_authority_m": 800.0}, headers=admin_headers
    )
    assert backwards.status_code == 422
    assert "must move the EoA forward" in backwards.json()["detail"]["message"]
    missing = client.post(f"{MA}/shorten", json={}, headers=admin_headers)
    assert missing.status_code == 422
    assert "end_of_authority_m" in missing.text
    bad_vehicle = client.post("/api/v1/rbc/no%20such/ma", json=ISSUE, headers=admin_headers)
    assert bad_vehicle.status_code == 422


def test_a_speed_restriction_is_sent_in_si_units_and_a_bad_one_refused(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    tsr = {"id": "works", "line_id": "bologna-ring", "start_m": 400.0, "end_m": 600.0}
    sent = client.post(
        "/api/v1/rbc/URV1/tsr", json=tsr | {"speed_kmh": 30.0}, headers=admin_headers
    )
    assert sent.status_code == 201, sent.text
    assert sent.json()["speed_mps"] == pytest.approx(30.0 * MPS_PER_KMH, abs=1e-12)
    revoked = client.delete(
        "/api/v1/rbc/URV1/tsr/works",
        params={"line_id": "bologna-ring", "start_m": 600.0, "end_m": 400.0},
        headers=admin_headers,
    )
    assert revoked.status_code == 422
    detail = revoked.json()["detail"]
    assert detail["message"] == "not a speed restriction"
    assert "end_m must lie after start_m" in detail["problems"][0]


def test_roles(client: TestClient, admin_headers: dict[str, str]) -> None:
    for username, role in (("olga", "observer"), ("dario", "driver")):
        created = client.post(
            "/api/v1/users",
            json={"username": username, "password": "password-1", "role": role},
            headers=admin_headers,
        )
        assert created.status_code == 201
    observer = login(client, "olga", "password-1")
    driver = login(client, "dario", "password-1")
    assert client.get(MA).status_code == 401
    assert client.post(MA, json=ISSUE).status_code == 401
    for headers in (observer, driver):
        assert client.post(MA, json=ISSUE, headers=headers).status_code == 403
    assert client.post(MA, json=ISSUE, headers=admin_headers).status_code == 201
    for headers in (observer, driver):
        extend = client.post(f"{MA}/extend", json={"end_of_authority_m": 990.0}, headers=headers)
        assert extend.status_code == 403
        assert client.delete(MA, headers=headers).status_code == 403
        assert client.get(MA, headers=headers).status_code == 200
    assert client.get(MA, headers=admin_headers).json()["movement_authority"]["ma_id"] == 1


def test_openapi_describes_the_rbc_routes(client: TestClient) -> None:
    paths = client.get("/openapi.json").json()["paths"]
    assert set(paths[MA.replace("URV1", "{vehicle_id}")]) == {"get", "post", "delete"}
    for action in ("extend", "shorten"):
        assert "post" in paths[f"/api/v1/rbc/{{vehicle_id}}/ma/{action}"]
