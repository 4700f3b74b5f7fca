"""Trackside fixtures: the real app on a real database and a real Zenoh session."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import pytest
import zenoh
from fastapi.testclient import TestClient

from protocol import ZenohSettings, open_session
from tests.conftest import WAIT_S, running_router
from trackdb import TrackMap, load_seed_line
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
            "database_url": database_url,
            "admin_user": ADMIN[0],
            "admin_password": ADMIN[1],
        }
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


# -- a live vehicle behind the service ---------------------------------------------------------

USERS = {
    "observer": ("olivia", "observer-pw", "observer"),
    "driver": ("alice", "alice-password", "driver"),
    "other_driver": ("bob", "bob-password", "driver"),
}


@pytest.fixture(scope="module")
def module_router() -> Iterator[str]:
    """A Zenoh router shared by a module's tests (starting vehicles is the costly part)."""
    with running_router() as endpoint:
        yield endpoint


@contextmanager
def running_vehicle(endpoint: str, vehicle_id: str = "URV1", speed: float = 1.0) -> Iterator[Any]:
    """A real onboard node (VC fitted) in real time on its own session and thread."""
    from onboard.node import OnboardNode, OnboardSettings
    from onboard.runtime import RealTimeClock

    with open_session(ZenohSettings(connect=(endpoint,))) as session:
        node = OnboardNode(
            OnboardSettings(vehicle_id=vehicle_id),
            session=session,
            clock=RealTimeClock(speed),
            track_map=TrackMap(load_seed_line("bologna-ring")),
        )
        runner = threading.Thread(target=node.run, daemon=True)
        runner.start()
        try:
            yield node
        finally:
            node.stop()
            runner.join(WAIT_S)
            node.close()


@contextmanager
def running_service(endpoint: str, database_url: str, **overrides: Any) -> Iterator[TestClient]:
    """The real app on its own Zenoh session, with the users of :data:`USERS`."""
    values: dict[str, Any] = {
        "database_url": database_url,
        "admin_user": ADMIN[0],
        "admin_password": ADMIN[1],
        "zenoh_connect": (endpoint,),
        "command_timeout_s": 3.0,
    }
    with TestClient(create_app(Settings(**(values | overrides)))) as client:
        admin = login(client, *ADMIN)
        for username, password, role in USERS.values():
            body = {"username": username, "password": password, "role": role}
            created = client.post("/api/v1/users", json=body, headers=admin)
            assert created.status_code in (201, 409), created.text
        yield client


def headers_of(client: TestClient, who: str) -> dict[str, str]:
    if who == "admin":
        return login(client, *ADMIN)
    username, password, _ = USERS[who]
    return login(client, username, password)
