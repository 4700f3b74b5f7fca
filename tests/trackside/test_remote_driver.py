"""The remote-driver API against a real onboard node: holds, commands, audit, history, live.

The auth matrix covers every route of the OpenAPI schema (so a new route cannot be forgotten)
× (no token, observer, driver not holding, driver holding, admin), on SQLite and PostgreSQL.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from protocol import messages as m
from tests.conftest import _postgres_database, wait_for
from tests.trackside.conftest import headers_of, running_service, running_vehicle

pytestmark = pytest.mark.e2e

V = "/api/v1/vehicles/URV1"
PRINCIPALS = ("none", "observer", "other_driver", "driver", "admin")
COMMANDS: dict[str, dict[str, Any]] = {
    "engage": {},
    "disengage": {},
    "rd-target-speed": {"target_speed_kmh": 0.0},
    "emergency-brake": {},
    "confirmations/eb-rearm": {"number": 0},
    "confirmations/etcs-isolation": {"number": 0},
    "confirmations/etcs-insertion": {"number": 0},
    "confirmations/vigilance-ack": {"number": 0},
    "skip-stop": {"timing_point_id": "east"},
    "train-hold": {"hold": False},
}
JOURNEY = {
    "id": "matrix",
    "line_id": "bologna-ring",
    "start_position_m": 0.0,
    "max_speed_mps": 10.0,
    "timing_points": [
        {
            "id": "east",
            "stopping_point_id": "east",
            "arrival_time_s": 400.0,
            "end_of_journey": True,
        },
    ],
}
MA = {"line_id": "bologna-ring", "start_m": 100.0, "end_of_authority_m": 900.0}
TSR = {
    "id": "works",
    "line_id": "bologna-ring",
    "start_m": 4000.0,
    "end_m": 4200.0,
    "speed_kmh": 30.0,
}


@pytest.fixture(
    scope="module", params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)]
)
def service(
    request: pytest.FixtureRequest, module_router: str, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[TestClient]:
    """The service with URV1 alive behind it, a stored journey, and URV1 in session."""
    if request.param == "sqlite":
        urls: Iterator[str] = iter([f"sqlite:///{tmp_path_factory.mktemp('db') / 'ts.db'}"])
    else:
        urls = _postgres_database()
    url = next(urls)
    try:
        with running_service(module_router, url) as client, running_vehicle(module_router):
            admin = headers_of(client, "admin")
            assert client.post("/api/v1/journeys", json=JOURNEY, headers=admin).status_code == 201
            assert wait_for(lambda: client.app.state.bridge.session_open("URV1"), 10.0)  # type: ignore[attr-defined]
            yield client
    finally:
        for _ in urls:  # the PostgreSQL schema is dropped when the generator ends
            pass


@dataclass
class Rule:
    """Who may call a route, and what the permitted callers get."""

    role: str  # "observer", "driver" or "admin"
    ok: int | tuple[int, ...] = 200
    hold: bool = False
    """Only the vehicle's holder (others get 409)."""
    json: Callable[[], Any] | None = None
    params: dict[str, Any] = field(default_factory=dict)
    prepare: Callable[[TestClient], None] | None = None


def _new_user() -> dict[str, str]:
    return {"username": f"u{uuid.uuid4().hex[:10]}", "password": "password-1", "role": "observer"}


def _returning(body: dict[str, Any]) -> Callable[[], dict[str, Any]]:
    return lambda: body


def _ensure_mallory(client: TestClient) -> None:
    """The user the matrix disables, enables and gives a new password."""
    body = {"username": "mallory", "password": "password-1", "role": "observer"}
    created = client.post("/api/v1/users", json=body, headers=headers_of(client, "admin"))
    assert created.status_code in (201, 409), created.text


def _issue_ma(client: TestClient) -> None:
    response = client.post("/api/v1/rbc/URV1/ma", json=MA, headers=headers_of(client, "admin"))
    assert response.status_code == 201, response.text


RULES: dict[tuple[str, str], Rule] = {
    ("POST", "/api/v1/auth/logout"): Rule("observer", 204),
    ("GET", "/api/v1/users/me"): Rule("observer"),
    ("POST", "/api/v1/users"): Rule("admin", 201, json=_new_user),
    ("POST", "/api/v1/users/{username}/disable"): Rule("admin", prepare=_ensure_mallory),
    ("POST", "/api/v1/users/{username}/enable"): Rule("admin", prepare=_ensure_mallory),
    ("POST", "/api/v1/users/{username}/password"): Rule(
        "admin", json=lambda: {"password": "password-2"}, prepare=_ensure_mallory
    ),
    ("GET", "/api/v1/vehicles"): Rule("observer"),
    ("GET", "/api/v1/vehicles/{vehicle_id}"): Rule("observer"),
    ("POST", "/api/v1/vehicles/{vehicle_id}/select"): Rule("driver", hold=True),
    ("POST", "/api/v1/vehicles/{vehicle_id}/release"): Rule("driver", hold=True),
    ("POST", "/api/v1/vehicles/{vehicle_id}/journey-profile"): Rule(
        "driver", hold=True, json=lambda: {"journey_id": "matrix"}
    ),
    # One route for the four confirmations; the matrix calls it with the kind in PATH_VALUES.
    ("POST", "/api/v1/vehicles/{vehicle_id}/confirmations/{kind}"): Rule(
        "driver", hold=True, json=lambda: {"number": 0}
    ),
    ("GET", "/api/v1/vehicles/{vehicle_id}/events"): Rule("observer"),
    ("GET", "/api/v1/vehicles/{vehicle_id}/telemetry"): Rule("observer"),
    ("GET", "/api/v1/lines"): Rule("observer"),
    ("POST", "/api/v1/lines"): Rule("admin", 422, json=lambda: {"id": "not-a-line"}),
    ("GET", "/api/v1/lines/{line_id}"): Rule("observer"),
    ("GET", "/api/v1/lines/{line_id}/export"): Rule("observer"),
    ("GET", "/api/v1/lines/{line_id}/version"): Rule("observer"),
    ("GET", "/api/v1/lines/{line_id}/versions"): Rule("observer"),
    ("GET", "/api/v1/lines/{line_id}/profile"): Rule("observer", params={"step": 100}),
    ("POST", "/api/v1/journeys/validate"): Rule("observer", json=lambda: JOURNEY),
    ("GET", "/api/v1/journeys"): Rule("observer"),
    ("POST", "/api/v1/journeys"): Rule("driver", 201, json=lambda: JOURNEY),
    ("GET", "/api/v1/journeys/{journey_id}"): Rule("observer"),
    ("GET", "/api/v1/rbc/{vehicle_id}/ma"): Rule("observer", prepare=_issue_ma),
    ("GET", "/api/v1/rbc/{vehicle_id}/tsr"): Rule("observer"),
    ("POST", "/api/v1/rbc/{vehicle_id}/ma"): Rule("admin", 201, json=lambda: MA),
    ("DELETE", "/api/v1/rbc/{vehicle_id}/ma"): Rule("admin", prepare=_issue_ma),
    ("POST", "/api/v1/rbc/{vehicle_id}/ma/extend"): Rule(
        "admin", json=lambda: {"end_of_authority_m": 1500.0}, prepare=_issue_ma
    ),
    ("POST", "/api/v1/rbc/{vehicle_id}/ma/shorten"): Rule(
        "admin", json=lambda: {"end_of_authority_m": 800.0}, prepare=_issue_ma
    ),
    ("POST", "/api/v1/rbc/{vehicle_id}/tsr"): Rule("admin", 201, json=lambda: TSR),
    ("DELETE", "/api/v1/rbc/{vehicle_id}/tsr/{restriction_id}"): Rule(
        "admin", params={"line_id": "bologna-ring", "start_m": 4000.0, "end_m": 4200.0}
    ),
    ("GET", "/api/v1/audit"): Rule("admin"),
} | {
    ("POST", f"/api/v1/vehicles/{{vehicle_id}}/{name}"): Rule(
        # The emergency brake is any driver's, held or not (issue 20).
        "driver",
        hold=name != "emergency-brake",
        json=_returning(body),
    )
    for name, body in COMMANDS.items()
    if not name.startswith("confirmations/")
}
PUBLIC = {("POST", "/api/v1/auth/token"), ("GET", "/healthz")}
RANK = {"observer": 1, "driver": 2, "other_driver": 2, "admin": 3}
PATH_VALUES = {
    "vehicle_id": "URV1",
    "line_id": "bologna-ring",
    "journey_id": "matrix",
    "restriction_id": "works",
    "kind": "vigilance-ack",
    "username": "mallory",
}


def _expected(rule: Rule, principal: str, path: str) -> int | tuple[int, ...]:
    if principal == "none":
        return 401
    if RANK[principal] < RANK[rule.role]:
        return 403
    if rule.hold and principal != "driver":
        # The admin may release anyone's hold; every other hold route needs the holder.
        return rule.ok if path.endswith("/release") and principal == "admin" else 409
    return rule.ok


def _routes(client: TestClient) -> set[tuple[str, str]]:
    schema = client.get("/openapi.json").json()
    return {(method.upper(), path) for path, ops in schema["paths"].items() for method in ops}


def test_every_route_has_a_rule(service: TestClient) -> None:
    routes = _routes(service)
    assert routes - PUBLIC - set(RULES) == set(), "routes missing from the auth matrix"
    assert set(RULES) - routes == set(), "rules of routes that no longer exist"


def test_auth_matrix(service: TestClient) -> None:
    headers = {who: headers_of(service, who) for who in PRINCIPALS if who != "none"}
    holder = headers["driver"]

    def hold() -> None:
        release = service.post(f"{V}/release", headers=headers["admin"])
        assert release.status_code == 200
        assert service.post(f"{V}/select", headers=holder).status_code == 200

    failures: list[str] = []
    for (method, template), rule in sorted(RULES.items()):
        path = template.format(**PATH_VALUES)
        for principal in PRINCIPALS:
            hold()
            if rule.prepare is not None:
                rule.prepare(service)
            if template.endswith("/logout") and principal != "none":
                headers[principal] = headers_of(service, principal)
            auth = headers.get(principal, {})
            response = service.request(
                method,
                path,
                headers=auth,
                params=rule.params,
                json=None if rule.json is None else rule.json(),
            )
            expected = _expected(rule, principal, template)
            allowed = expected if isinstance(expected, tuple) else (expected,)
            if response.status_code not in allowed:
                failures.append(
                    f"{method} {template} as {principal}: {response.status_code} not {expected}"
                    f" ({response.text[:120]})"
                )
            if template.endswith("/logout") and principal != "none":
                again = service.get("/api/v1/users/me", headers=auth)
                if again.status_code != 401:
                    failures.append(f"token of {principal} still valid after logout")
                headers[principal] = headers_of(service, principal)
    assert failures == []


def test_a_second_driver_is_refused_while_the_first_holds(service: TestClient) -> None:
    alice, bob = headers_of(service, "driver"), headers_of(service, "other_driver")
    admin = headers_of(service, "admin")
    assert service.post(f"{V}/release", headers=admin).status_code == 200
    taken = service.post(f"{V}/select", headers=alice)
    assert taken.status_code == 200
    assert taken.json()["holder"] == "alice"
    assert service.post(f"{V}/select", headers=alice).json()["holder"] == "alice"  # idempotent
    refused = service.post(f"{V}/select", headers=bob)
    assert refused.status_code == 409
    assert refused.json()["detail"] == "URV1 is held by alice"
    command = service.post(f"{V}/rd-target-speed", json={"target_speed_kmh": 20}, headers=bob)
    assert command.status_code == 409
    assert "alice" in command.json()["detail"]
    assert service.post(f"{V}/release", headers=bob).status_code == 409
    listed = service.get(V, headers=bob).json()
    assert listed["holder"] == "alice"
    assert listed["simulated_operator"] is False
    assert service.post(f"{V}/release", headers=alice).json()["holder"] is None
    assert service.post(f"{V}/select", headers=bob).json()["holder"] == "bob"
    hint = service.post(f"{V}/engage", headers=alice)
    assert hint.status_code == 409
    assert hint.json()["detail"] == "URV1 is held by bob"
    assert service.post(f"{V}/release", headers=bob).status_code == 200
    assert service.post(f"{V}/engage", headers=alice).json()["detail"] == "select URV1 first"


def test_every_command_is_answered_by_the_vehicle_and_audited(service: TestClient) -> None:
    alice, admin = headers_of(service, "driver"), headers_of(service, "admin")
    assert service.post(f"{V}/release", headers=admin).status_code == 200
    assert service.post(f"{V}/select", headers=alice).status_code == 200
    answers: dict[str, dict[str, Any]] = {}
    for name, body in COMMANDS.items():
        response = service.post(f"{V}/{name}", json=body, headers=alice)
        assert response.status_code == 200, (name, response.text)
        answers[name] = response.json()
        assert answers[name]["vehicle_id"] == "URV1"
        assert answers[name]["accepted"] or answers[name]["reason"]
    # At power-up the VC holds the EB: nothing may engage yet, and the vehicle says why.
    assert answers["engage"]["accepted"] is False
    assert answers["emergency-brake"]["accepted"] is True
    audit = service.get(
        "/api/v1/audit", params={"vehicle_id": "URV1", "limit": 50}, headers=admin
    ).json()
    pairs: dict[Any, list[dict[str, Any]]] = {}
    for entry in audit:
        if entry["user"] == "alice":
            pairs.setdefault(entry["request"].get("command_id"), []).append(entry)
    by_id = {command_id: entries[-1] for command_id, entries in pairs.items()}
    for name, answer in answers.items():
        # The intent before the vehicle was asked, then the outcome (issue 20).
        intent, entry = pairs[answer["command_id"]]
        assert intent["result"] == "requested", name
        assert intent["request"]["request_id"] == entry["request"]["request_id"]
        assert entry["result"] == ("accepted" if answer["accepted"] else "refused"), name
        assert entry["detail"] == answer["reason"]
    actions = {entry["action"] for entry in by_id.values()}
    assert {"engage", "emergency_brake", "train_hold"} <= actions
    confirmed = {f"operator_confirm.{kind}" for kind in m.OperatorRequestKind}
    assert confirmed <= actions  # each path kind reaches the vehicle as its own request kind
    observer = service.get("/api/v1/audit", headers=headers_of(service, "observer"))
    assert observer.status_code == 403


def test_events_and_telemetry_history(service: TestClient) -> None:
    alice, admin = headers_of(service, "driver"), headers_of(service, "admin")
    assert service.post(f"{V}/release", headers=admin).status_code == 200
    assert service.post(f"{V}/select", headers=alice).status_code == 200
    assert service.post(f"{V}/emergency-brake", headers=alice).json()["accepted"] is True

    def events() -> list[dict[str, Any]]:
        return list(service.get(f"{V}/events", headers=alice).json())

    assert wait_for(lambda: any(e["code"] == "operator.emergency_brake" for e in events()))
    seqs = [event["seq"] for event in events()]
    assert seqs == sorted(seqs)
    assert len(service.get(f"{V}/events", params={"limit": 2}, headers=alice).json()) == 2

    def samples() -> list[dict[str, Any]]:
        return list(service.get(f"{V}/telemetry", headers=alice).json())

    assert wait_for(lambda: len(samples()) >= 3, 10.0)
    times = [sample["sim_time_s"] for sample in samples()]
    # One sample per second of the vehicle's time, at most.
    assert all(later - earlier > 0.5 for earlier, later in zip(times, times[1:], strict=False))
    assert samples()[-1]["eb"] is True
    since = service.get(f"{V}/telemetry", params={"since_s": times[-1]}, headers=alice).json()
    assert [sample["sim_time_s"] for sample in since][0] == times[-1]
    assert service.get(f"{V}/telemetry", params={"since_s": -1}, headers=alice).status_code == 422


def test_vehicle_websocket_pushes_status_and_events(service: TestClient) -> None:
    alice, admin = headers_of(service, "driver"), headers_of(service, "admin")
    assert service.post(f"{V}/release", headers=admin).status_code == 200
    assert service.post(f"{V}/select", headers=alice).status_code == 200
    token = alice["Authorization"].removeprefix("Bearer ")
    with service.websocket_connect("/api/v1/ws/vehicles/URV1") as socket:
        socket.send_json({"type": "auth", "token": "wrong"})
        with pytest.raises(WebSocketDisconnect) as refused:
            socket.receive_json()
    assert refused.value.code == 1008
    with service.websocket_connect("/api/v1/ws/vehicles/URV1") as socket:
        socket.send_json({"type": "auth", "token": token})
        frame = socket.receive_json()
        while frame["type"] != "status":
            frame = socket.receive_json()
        assert frame["status"]["vehicle_id"] == "URV1"
        assert frame["holder"] == "alice"
        assert frame["hold_expires_at"] is not None
        assert frame["simulated_operator"] is False
        assert "operator_requests" in frame["status"]["vital_control"]
        # The operator's emergency brake is accepted in every state (a train hold is refused
        # at once, with no event, until a journey is accepted), so this test runs alone too.
        answer = service.post(f"{V}/emergency-brake", headers=alice)
        assert answer.status_code == 200
        assert answer.json()["accepted"] is True
        codes: list[str] = []
        while "operator.emergency_brake" not in codes:
            frame = socket.receive_json()
            if frame["type"] == "event":
                codes.append(frame["event"]["code"])
                assert set(frame["event"]) == {
                    "sim_time_s",
                    "received_at",
                    "severity",
                    "code",
                    "text",
                    "seq",
                }


def test_logout_revokes_and_logins_are_rate_limited(service: TestClient) -> None:
    headers = headers_of(service, "observer")
    assert service.post("/api/v1/auth/logout", headers=headers).status_code == 204
    assert service.get("/api/v1/users/me", headers=headers).status_code == 401
    limiter = service.app.state.login_limiter  # type: ignore[attr-defined]
    name = f"nobody-{uuid.uuid4().hex[:6]}"
    codes = [
        service.post("/api/v1/auth/token", data={"username": name, "password": "x"}).status_code
        for _ in range(limiter.max_failures + 1)
    ]
    assert codes == [401] * limiter.max_failures + [429]
    # The address is blocked too, for every user, until the window passes.
    blocked = service.post("/api/v1/auth/token", data={"username": "olivia", "password": "x"})
    assert blocked.status_code == 429
    assert int(blocked.headers["Retry-After"]) >= 1
    limiter._failures.clear()  # the window passing, without waiting for it
    assert (
        service.post(
            "/api/v1/auth/token", data={"username": "olivia", "password": "observer-pw"}
        ).status_code
        == 200
    )
