"""Authentication and roles (CONTRACT.md §2), on SQLite and PostgreSQL."""

from __future__ import annotations

import json
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import create_engine, text
from sqlalchemy.orm import Session
from starlette.types import Message, Receive, Scope, Send

from tests.trackside.conftest import ADMIN, MakeClient, login
from trackside.config import Settings
from trackside.main import create_app
from trackside.models import Role
from trackside.services import users


def test_token_for_the_bootstrapped_admin(client: TestClient) -> None:
    response = client.post("/api/v1/auth/token", data={"username": ADMIN[0], "password": ADMIN[1]})
    assert response.status_code == 200
    body = response.json()
    assert body["token_type"] == "bearer"
    assert len(body["access_token"]) >= 32


@pytest.mark.parametrize(("username", "password"), [(ADMIN[0], "wrong"), ("nobody", "whatever")])
def test_wrong_credentials_are_401(client: TestClient, username: str, password: str) -> None:
    response = client.post("/api/v1/auth/token", data={"username": username, "password": password})
    assert response.status_code == 401
    assert response.json() == {"detail": "wrong username or password"}
    assert response.headers["WWW-Authenticate"] == "Bearer"


@pytest.mark.parametrize("path", ["/api/v1/vehicles", "/api/v1/vehicles/URV1", "/api/v1/users/me"])
def test_routes_need_a_token(client: TestClient, path: str) -> None:
    assert client.get(path).status_code == 401
    unknown = client.get(path, headers={"Authorization": "Bearer not-a-token"})
    assert unknown.status_code == 401
    assert unknown.json() == {"detail": "not authenticated"}  # not why
    assert unknown.headers["WWW-Authenticate"] == "Bearer"


def test_role_too_low_is_403(client: TestClient, admin_headers: dict[str, str]) -> None:
    created = client.post(
        "/api/v1/users",
        headers=admin_headers,
        json={"username": "olga", "password": "observer-pw", "role": "observer"},
    )
    assert created.status_code == 201
    observer = login(client, "olga", "observer-pw")
    assert client.get("/api/v1/users/me", headers=observer).json() == {
        "username": "olga",
        "role": "observer",
        "disabled": False,
    }
    assert client.get("/api/v1/vehicles", headers=observer).status_code == 200
    forbidden = client.post(
        "/api/v1/users",
        headers=observer,
        json={"username": "eve", "password": "password-x", "role": "admin"},
    )
    assert forbidden.status_code == 403
    assert forbidden.json() == {"detail": "admin role needed, olga is observer"}


def test_duplicate_user_is_409_and_bad_body_422(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    body = {"username": "dan", "password": "driver-pw", "role": "driver"}
    assert client.post("/api/v1/users", headers=admin_headers, json=body).status_code == 201
    duplicate = client.post("/api/v1/users", headers=admin_headers, json=body)
    assert duplicate.status_code == 409
    assert duplicate.json() == {"detail": "user 'dan' exists"}
    bad = body | {"role": "emperor"}
    assert client.post("/api/v1/users", headers=admin_headers, json=bad).status_code == 422


def test_admin_from_environment(
    make_client: MakeClient, monkeypatch: pytest.MonkeyPatch, database_url: str
) -> None:
    monkeypatch.setenv("ATO_ADMIN_USER", "envadmin")
    monkeypatch.setenv("ATO_ADMIN_PASSWORD", "from-the-env")
    from trackside.config import Settings

    settings = Settings(database_url=database_url)
    assert settings.admin_user == "envadmin"
    client = make_client(admin_user=settings.admin_user, admin_password=settings.admin_password)
    headers = login(client, "envadmin", "from-the-env")
    assert client.get("/api/v1/users/me", headers=headers).json()["role"] == "admin"


def test_no_admin_without_settings(make_client: MakeClient) -> None:
    client = make_client(admin_user=None, admin_password=None)
    response = client.post("/api/v1/auth/token", data={"username": ADMIN[0], "password": ADMIN[1]})
    assert response.status_code == 401


def test_expired_token_is_401(make_client: MakeClient) -> None:
    client = make_client(token_ttl_s=1e-6)
    headers = login(client, *ADMIN)
    expired = client.get("/api/v1/users/me", headers=headers)
    assert expired.status_code == 401
    assert expired.json() == {"detail": "not authenticated"}


def test_passwords_and_tokens_are_not_stored_in_clear(
    client: TestClient, database_url: str
) -> None:
    headers = login(client, *ADMIN)
    token = headers["Authorization"].split()[1]
    engine = create_engine(database_url.replace("postgresql+psycopg", "postgresql+psycopg"))
    with engine.connect() as connection:
        stored_hash = connection.execute(text("SELECT password_hash FROM users")).scalar_one()
        token_hashes = connection.execute(text("SELECT token_hash FROM api_tokens")).scalars().all()
    engine.dispose()
    assert stored_hash.startswith("scrypt$")
    assert ADMIN[1] not in stored_hash
    assert token not in token_hashes
    assert len(token_hashes) == 1


def test_openapi_describes_every_route(client: TestClient) -> None:
    paths = client.get("/openapi.json").json()["paths"]
    for path in (
        "/api/v1/auth/token",
        "/api/v1/vehicles",
        "/api/v1/vehicles/{vehicle_id}",
        "/api/v1/users",
        "/api/v1/users/me",
    ):
        assert path in paths


def test_what_a_route_writes_is_committed_before_its_answer_is_sent(
    database_url: str, zenoh_pair: tuple[Any, Any]
) -> None:
    """The console asks for the fleet the moment sign-in answers: the token must already be
    committed then, or that request races the commit and gets a 401 (seen on a loaded CI host).
    A second connection checks the token while the answer's body is being sent."""
    settings = Settings(
        database_url=database_url,
        admin_user=ADMIN[0],
        admin_password=ADMIN[1],
    )
    app = create_app(settings, zenoh_session=zenoh_pair[0])
    engine = create_engine(database_url)
    seen: list[str] = []

    async def checking_app(scope: Scope, receive: Receive, send: Send) -> None:
        async def checking_send(message: Message) -> None:
            if message["type"] == "http.response.body" and message.get("body"):
                token = json.loads(message["body"])["access_token"]
                with Session(engine) as db:
                    seen.append(users.resolve_token(db, token).username)
            await send(message)

        await app(scope, receive, checking_send if scope["type"] == "http" else send)

    try:
        with TestClient(checking_app) as client:
            login(client, *ADMIN)
    finally:
        engine.dispose()
    assert seen == [ADMIN[0]]


def test_a_token_user_has_no_password_to_log_in_with(client: TestClient) -> None:
    """A user made by ``ensure_token_user`` (a scenario run's operator) acts through the token
    issued to it; no password logs it in, not even the empty hash's own text."""
    factory = client.app.state.session_factory  # type: ignore[attr-defined]
    with factory() as db, db.begin():
        user = users.ensure_token_user(db, "runner", Role.ADMIN)
        assert users.ensure_token_user(db, "runner", Role.ADMIN).id == user.id
        token = users.issue_token(db, user, 60.0)
    me = client.get("/api/v1/users/me", headers={"Authorization": f"Bearer {token}"})
    assert me.json() == {"username": "runner", "role": "admin", "disabled": False}
    for password in ("", "!", users.NO_PASSWORD, "runner"):
        answer = client.post(
            "/api/v1/auth/token", data={"username": "runner", "password": password}
        )
        assert answer.status_code in (401, 422)  # 422: an empty form field
        assert "access_token" not in answer.json()
