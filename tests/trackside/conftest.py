"""Trackside fixtures: the real app on a real database and a real Zenoh session."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest
import zenoh
from fastapi.testclient import TestClient

from trackside.config import Settings
from trackside.main import create_app

ADMIN = ("root", "admin-password")
MakeClient = Callable[..., TestClient]


@pytest.fixture
def make_client(
    database_url: str, zenoh_pair: tuple[zenoh.Session, zenoh.Session]
) -> Iterator[MakeClient]:
    trackside_session, _ = zenoh_pair
    clients: list[TestClient] = []

    def make(**overrides: object) -> TestClient:
        values: dict[str, object] = {
            "database_url": database_url, "admin_user": ADMIN[0], "admin_password": ADMIN[1],
        }  # fmt: skip
        settings = Settings(**(values | overrides))  # type: ignore[arg-type]
        client = TestClient(create_app(settings, zenoh_session=trackside_session))
        client.__enter__()
        clients.append(client)
        return client

    yield make
    for client in clients:
        client.__exit__(None, None, None)


@pytest.fixture
def client(make_client: MakeClient) -> TestClient:
    return make_client()


def login(client: TestClient, username: str, password: str) -> dict[str, str]:
    response = client.post("/api/v1/auth/token", data={"username": username, "password": password})
    assert response.status_code == 200, response.text
    return {"Authorization": f"Bearer {response.json()['access_token']}"}


@pytest.fixture
def admin_headers(client: TestClient) -> dict[str, str]:
    return login(client, *ADMIN)
