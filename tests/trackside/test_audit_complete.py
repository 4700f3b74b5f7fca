"""Every mutating route leaves its audit entries (issue 20): one table over the OpenAPI schema.

Each mutating route (POST, PUT, PATCH, DELETE) of the schema has an entry in :data:`CALLS`
saying how to call it successfully and what it must leave in the audit log: exactly one entry
(``accepted``), or, for a request to a vehicle, exactly its intent (``requested``) and its
outcome, sharing one ``request_id``. A new mutating route without an entry fails the test. The
service is the real one, on SQLite and PostgreSQL, with a real onboard node behind it; the log
it leaves verifies (``ato audit verify``).
"""

from __future__ import annotations

import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest
from fastapi.testclient import TestClient
from typer.testing import CliRunner

from deploy.cli import app as cli
from tests.conftest import _postgres_database, wait_for
from tests.trackside.conftest import ADMIN, headers_of, running_service, running_vehicle
from tests.trackside.test_remote_driver import JOURNEY as MATRIX_JOURNEY
from tests.trackside.test_remote_driver import MA, TSR

pytestmark = pytest.mark.e2e

V = "/api/v1/vehicles/{vehicle_id}"
JOURNEY = {**MATRIX_JOURNEY, "id": "audited"}
MUTATING = {"POST", "PUT", "PATCH", "DELETE"}


@dataclass
class Run:
    """What a call needs that its preparation made: a fresh user, a fresh token."""

    client: TestClient
    admin: dict[str, str]
    username: str = ""
    headers: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Call:
    """How to call a route successfully, and the audit entries it must leave."""

    who: str
    """``none``, ``observer``, ``driver`` or ``admin``."""
    audit: str
    """``one`` (one accepted entry), ``vehicle`` (intent and outcome) or ``none``."""
    action: str | None = None
    ok: tuple[int, ...] = (200,)
    json: Callable[[Run], Any] | None = None
    data: Callable[[Run], Any] | None = None
    content: Callable[[Run], bytes] | None = None
    params: dict[str, Any] = field(default_factory=dict)
    prepare: Callable[[Run], None] | None = None
    why: str = ""
    """Why a mutating route leaves no entry."""


def _hold(run: Run) -> None:
    assert run.client.post("/api/v1/vehicles/URV1/release", headers=run.admin).status_code == 200
    driver = headers_of(run.client, "driver")
    assert run.client.post("/api/v1/vehicles/URV1/select", headers=driver).status_code == 200


def _free(run: Run) -> None:
    assert run.client.post("/api/v1/vehicles/URV1/release", headers=run.admin).status_code == 200


def _new_user(run: Run) -> None:
    run.username = f"u{uuid.uuid4().hex[:10]}"
    body = {"username": run.username, "password": "password-1", "role": "observer"}
    assert run.client.post("/api/v1/users", json=body, headers=run.admin).status_code == 201


def _fresh_token(run: Run) -> None:
    run.headers = headers_of(run.client, "observer")


def _issue_ma(run: Run) -> None:
    response = run.client.post("/api/v1/rbc/URV1/ma", json=MA, headers=run.admin)
    assert response.status_code == 201, response.text


def _line_document(run: Run) -> bytes:
    exported = run.client.get("/api/v1/lines/bologna-ring/export", headers=run.admin)
    assert exported.status_code == 200
    return exported.content


def _command(name: str, body: dict[str, Any]) -> tuple[tuple[str, str], Call]:
    # The emergency brake is any driver's; the others need the hold.
    prepare = _free if name == "emergency-brake" else _hold
    return ("POST", f"{V}/{name}"), Call("driver", "vehicle", json=lambda _: body, prepare=prepare)


COMMANDS: dict[str, dict[str, Any]] = {
    "engage": {},
    "disengage": {},
    "rd-target-speed": {"target_speed_kmh": 0.0},
    "emergency-brake": {},
    "skip-stop": {"timing_point_id": "east"},
    "train-hold": {"hold": False},
}
CALLS: dict[tuple[str, str], Call] = {
    ("POST", "/api/v1/auth/token"): Call(
        "none", "one", "login", data=lambda _: {"username": ADMIN[0], "password": ADMIN[1]}
    ),
    ("POST", "/api/v1/auth/logout"): Call(
        "observer", "one", "logout", (204,), prepare=_fresh_token
    ),
    ("POST", "/api/v1/users"): Call(
        "admin",
        "one",
        "user.create",
        (201,),
        json=lambda _: {
            "username": f"u{uuid.uuid4().hex[:10]}",
            "password": "password-1",
            "role": "driver",
        },
    ),
    ("POST", "/api/v1/users/{username}/disable"): Call(
        "admin", "one", "user.disable", prepare=_new_user
    ),
    ("POST", "/api/v1/users/{username}/enable"): Call(
        "admin", "one", "user.enable", prepare=_new_user
    ),
    ("POST", "/api/v1/users/{username}/password"): Call(
        "admin",
        "one",
        "user.password",
        json=lambda _: {"password": "a-new-password"},
        prepare=_new_user,
    ),
    ("POST", f"{V}/select"): Call("driver", "one", "select", prepare=_free),
    ("POST", f"{V}/release"): Call("driver", "one", "release", prepare=_hold),
    ("POST", f"{V}/journey-profile"): Call(
        "driver",
        "vehicle",
        "journey_profile",
        json=lambda _: {"journey_id": "audited"},
        prepare=_hold,
    ),
    ("POST", f"{V}/confirmations/{{kind}}"): Call(
        "driver",
        "vehicle",
        "operator_confirm.vigilance",
        json=lambda _: {"number": 0},
        prepare=_hold,
    ),
    ("POST", "/api/v1/lines"): Call(
        "admin", "one", "line.import", (200, 201), content=_line_document
    ),
    ("POST", "/api/v1/journeys/validate"): Call(
        "observer", "none", json=lambda _: JOURNEY, why="it checks a journey, it stores nothing"
    ),
    ("POST", "/api/v1/journeys"): Call(
        "driver", "one", "journey.create", (201,), json=lambda _: JOURNEY
    ),
    ("POST", "/api/v1/rbc/{vehicle_id}/ma"): Call(
        "admin", "one", "rbc.ma_issue", (201,), json=lambda _: MA
    ),
    ("DELETE", "/api/v1/rbc/{vehicle_id}/ma"): Call(
        "admin", "one", "rbc.ma_revoke", prepare=_issue_ma
    ),
    ("POST", "/api/v1/rbc/{vehicle_id}/ma/extend"): Call(
        "admin",
        "one",
        "rbc.ma_extend",
        json=lambda _: {"end_of_authority_m": 1500.0},
        prepare=_issue_ma,
    ),
    ("POST", "/api/v1/rbc/{vehicle_id}/ma/shorten"): Call(
        "admin",
        "one",
        "rbc.ma_shorten",
        json=lambda _: {"end_of_authority_m": 800.0},
        prepare=_issue_ma,
    ),
    ("POST", "/api/v1/rbc/{vehicle_id}/tsr"): Call(
        "admin", "one", "rbc.tsr_issue", (201,), json=lambda _: TSR
    ),
    ("DELETE", "/api/v1/rbc/{vehicle_id}/tsr/{restriction_id}"): Call(
        "admin",
        "one",
        "rbc.tsr_revoke",
        params={"line_id": "bologna-ring", "start_m": 4000.0, "end_m": 4200.0},
    ),
} | dict(_command(name, body) for name, body in COMMANDS.items())


@pytest.fixture(
    scope="module", params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)]
)
def service(
    request: pytest.FixtureRequest, module_router: str, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[TestClient, str]]:
    """The service with URV1 alive and in session behind it, a stored journey; and its URL."""
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
            yield client, url
    finally:
        for _ in urls:  # the PostgreSQL schema is dropped when the generator ends
            pass


def _mutating_routes(client: TestClient) -> set[tuple[str, str]]:
    schema = client.get("/openapi.json").json()
    return {
        (method.upper(), path)
        for path, operations in schema["paths"].items()
        for method in operations
        if method.upper() in MUTATING
    }


def _last_id(client: TestClient, admin: dict[str, str]) -> int:
    entries = client.get("/api/v1/audit", params={"limit": 1}, headers=admin).json()
    return int(entries[-1]["id"]) if entries else 0


def _entries_since(client: TestClient, admin: dict[str, str], last_id: int) -> list[Any]:
    entries = client.get("/api/v1/audit", params={"limit": 100}, headers=admin).json()
    return [entry for entry in entries if entry["id"] > last_id]


def _problems(call: Call, who: str, entries: list[dict[str, Any]]) -> list[str]:
    """What is wrong with the entries a call left (an empty list when they are right)."""
    if call.audit == "none":
        return [f"{len(entries)} entries, none expected"] if entries else []
    if call.audit == "one":
        if len(entries) != 1:
            return [f"{len(entries)} entries, not one: {entries}"]
        (entry,) = entries
        wanted = (call.action, "accepted", who)
        found = (entry["action"], entry["result"], entry["user"])
        return [] if found == wanted else [f"{found} is not {wanted}"]
    if len(entries) != 2:
        return [f"{len(entries)} entries, not intent and outcome: {entries}"]
    intent, outcome = entries
    problems = []
    if (intent["result"], outcome["result"]) not in {
        ("requested", "accepted"),
        ("requested", "refused"),
    }:
        problems.append(f"results {intent['result']}, {outcome['result']}")
    if intent["request"]["request_id"] != outcome["request"].get("request_id"):
        problems.append("intent and outcome do not share their request id")
    if intent["action"] != outcome["action"] or (
        call.action is not None and intent["action"] != call.action
    ):
        problems.append(f"actions {intent['action']}, {outcome['action']}")
    if intent["vehicle_id"] != "URV1" or intent["user"] != who:
        problems.append(f"intent by {intent['user']} on {intent['vehicle_id']}")
    return problems


def _call(run: Run, method: str, path: str, call: Call) -> Any:
    headers = run.headers or ({} if call.who == "none" else headers_of(run.client, call.who))
    return run.client.request(
        method,
        path,
        headers=headers,
        params=call.params,
        json=None if call.json is None else call.json(run),
        data=None if call.data is None else call.data(run),
        content=None if call.content is None else call.content(run),
    )


USER_NAMES = {"none": ADMIN[0], "observer": "olivia", "driver": "alice", "admin": ADMIN[0]}
PATH_VALUES = {
    "vehicle_id": "URV1",
    "journey_id": "audited",
    "restriction_id": "works",
    "kind": "vigilance-ack",
}


def test_every_mutating_route_has_an_entry(service: tuple[TestClient, str]) -> None:
    routes = _mutating_routes(service[0])
    assert routes - set(CALLS) == set(), "mutating routes missing from the audit table"
    assert set(CALLS) - routes == set(), "entries of routes that no longer exist"
    assert all(call.why for call in CALLS.values() if call.audit == "none")


def test_each_mutating_route_leaves_exactly_its_audit_entries(
    service: tuple[TestClient, str],
) -> None:
    client, url = service
    admin = headers_of(client, "admin")
    failures: list[str] = []
    for (method, template), call in sorted(CALLS.items()):
        run = Run(client, admin)
        if call.prepare is not None:
            call.prepare(run)
        path = template.format(**(PATH_VALUES | {"username": run.username}))
        # Logged in before the count starts: a login is an entry of its own.
        run.headers = run.headers or (
            {} if call.who == "none" else headers_of(run.client, call.who)
        )
        before = _last_id(client, admin)
        response = _call(run, method, path, call)
        if response.status_code not in call.ok:
            failures.append(f"{method} {template}: {response.status_code} {response.text[:160]}")
            continue
        entries = _entries_since(client, admin, before)
        who = USER_NAMES[call.who]
        failures += [f"{method} {template}: {p}" for p in _problems(call, who, entries)]
    assert failures == []
    verified = CliRunner().invoke(cli, ["audit", "verify", "--database", url])
    assert verified.exit_code == 0, verified.output


def test_a_refused_call_leaves_one_refused_entry(service: tuple[TestClient, str]) -> None:
    client, _ = service
    admin = headers_of(client, "admin")
    bob = headers_of(client, "other_driver")
    _hold(Run(client, admin))
    before = _last_id(client, admin)
    taken = client.post("/api/v1/vehicles/URV1/select", headers=bob)
    assert taken.status_code == 409
    shortened = client.post(
        "/api/v1/rbc/NOBODY/ma/shorten", json={"end_of_authority_m": 10.0}, headers=admin
    )
    assert shortened.status_code == 404
    entries = _entries_since(client, admin, before)
    assert [(e["user"], e["action"], e["result"]) for e in entries] == [
        ("bob", "select", "refused"),
        ("root", "rbc.ma_shorten", "refused"),
    ]
    assert entries[0]["detail"] == "URV1 is held by alice"


def test_a_command_the_trackside_refuses_leaves_its_intent_and_outcome(
    service: tuple[TestClient, str],
) -> None:
    client, _ = service
    admin = headers_of(client, "admin")
    bob = headers_of(client, "other_driver")
    _hold(Run(client, admin))
    before = _last_id(client, admin)
    refused = client.post("/api/v1/vehicles/URV1/engage", headers=bob)
    assert refused.status_code == 409
    intent, outcome = _entries_since(client, admin, before)
    assert (intent["result"], outcome["result"]) == ("requested", "refused")
    assert intent["request"]["request_id"] == outcome["request"]["request_id"]
    assert outcome["detail"] == "URV1 is held by alice"
