"""Holds are leases (issue 20): they end unless the holder renews them, by selecting again, by a
command or while their console is connected; an expired hold is free for another driver."""

from __future__ import annotations

import time
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta

import pytest
import zenoh
from alembic import command
from alembic.config import Config
from fastapi.testclient import TestClient
from sqlalchemy import text

from protocol import declare_liveliness
from tests.conftest import wait_for
from tests.trackside.conftest import ADMIN, MakeClient, login
from trackside.db import MIGRATIONS_DIR, create_database_engine, migrate

V = "/api/v1/vehicles/URV7"
LEASE_S = 1.0
"""Short, so that the tests see leases end; the service's default is 60 s."""


@pytest.fixture
def alive_urv7(zenoh_pair: tuple[zenoh.Session, zenoh.Session]) -> Iterator[None]:
    """URV7's liveliness token, so that it can be selected (it answers no command)."""
    _, onboard = zenoh_pair
    token = declare_liveliness(onboard, "ato/alive/ob/URV7")
    yield
    token.undeclare()


@pytest.fixture
def leasing(make_client: MakeClient, alive_urv7: None) -> TestClient:
    """The service with one-second leases, URV7 alive, drivers alice and bob."""
    del alive_urv7
    client = make_client(hold_lease_s=LEASE_S, command_timeout_s=0.2)
    admin = login(client, *ADMIN)
    for name in ("alice", "bob"):
        body = {"username": name, "password": f"{name}-password", "role": "driver"}
        assert client.post("/api/v1/users", json=body, headers=admin).status_code == 201
    assert wait_for(lambda: client.get(V, headers=admin).status_code == 200)
    return client


def _driver(client: TestClient, name: str) -> dict[str, str]:
    return login(client, name, f"{name}-password")


def _expiry(answer: dict[str, object], key: str = "expires_at") -> datetime:
    value = answer[key]
    assert isinstance(value, str)
    return datetime.fromisoformat(value)


def _holder(client: TestClient, headers: dict[str, str]) -> dict[str, object]:
    listed = {v["id"]: v for v in client.get("/api/v1/vehicles", headers=headers).json()}
    return {key: listed["URV7"][key] for key in ("holder", "hold_expires_at")}


def test_a_hold_shows_the_end_of_its_lease(leasing: TestClient) -> None:
    alice = _driver(leasing, "alice")
    before = datetime.now(UTC)
    answer = leasing.post(f"{V}/select", headers=alice).json()
    expires = _expiry(answer)
    assert before + timedelta(seconds=LEASE_S) <= expires
    assert expires <= datetime.now(UTC) + timedelta(seconds=LEASE_S)
    listed = _holder(leasing, alice)
    assert listed["holder"] == "alice"
    assert _expiry(listed, "hold_expires_at") == expires
    assert _expiry(leasing.get(V, headers=alice).json(), "hold_expires_at") == expires


def test_an_expired_hold_is_free_for_another_driver(leasing: TestClient) -> None:
    alice, bob = _driver(leasing, "alice"), _driver(leasing, "bob")
    assert leasing.post(f"{V}/select", headers=alice).status_code == 200
    assert leasing.post(f"{V}/select", headers=bob).status_code == 409
    assert wait_for(lambda: _holder(leasing, bob)["holder"] is None, 3 * LEASE_S)
    assert _holder(leasing, bob)["hold_expires_at"] is None
    # Alice's commands are refused from then on, and she is told why.
    refused = leasing.post(f"{V}/engage", headers=alice)
    assert refused.status_code == 409
    assert "expired" in refused.json()["detail"]
    taken = leasing.post(f"{V}/select", headers=bob)
    assert taken.status_code == 200
    assert taken.json()["holder"] == "bob"
    assert leasing.post(f"{V}/select", headers=alice).status_code == 409


def test_selecting_again_and_commanding_renew_the_lease(leasing: TestClient) -> None:
    alice = _driver(leasing, "alice")
    # A quarter of the lease passes between the calls: the expiry must move, and the three
    # quarters left cover a request's way through a loaded machine (half a second did not, in
    # a full run beside other work: the lease ran out first).
    first = _expiry(leasing.post(f"{V}/select", headers=alice).json())
    assert wait_for(lambda: datetime.now(UTC) > first - timedelta(seconds=LEASE_S * 3 / 4))
    second = _expiry(leasing.post(f"{V}/select", headers=alice).json())
    assert second > first
    assert wait_for(lambda: datetime.now(UTC) > second - timedelta(seconds=LEASE_S * 3 / 4))
    # URV7 answers no command (504), but the holder's command has renewed the hold first.
    assert leasing.post(f"{V}/engage", headers=alice).status_code == 504
    third = _expiry(_holder(leasing, alice), "hold_expires_at")
    assert third > second


def test_a_connected_console_keeps_its_hold_and_a_closed_one_loses_it(
    leasing: TestClient,
) -> None:
    alice = _driver(leasing, "alice")
    token = alice["Authorization"].removeprefix("Bearer ")
    first = _expiry(leasing.post(f"{V}/select", headers=alice).json())
    with leasing.websocket_connect("/api/v1/ws/session") as console:
        console.send_json({"type": "auth", "token": token})
        frame = console.receive_json()
        assert frame["type"] == "holds"
        assert set(frame["holds"]) == {"URV7"}
        # Two leases later the hold is still there, renewed by the open console.
        time.sleep(2 * LEASE_S)
        renewed = _holder(leasing, alice)
        assert renewed["holder"] == "alice"
        assert _expiry(renewed, "hold_expires_at") > first + timedelta(seconds=LEASE_S)
        assert console.receive_json()["type"] == "holds"  # the new lease pushed
    assert wait_for(lambda: _holder(leasing, alice)["holder"] is None, 3 * LEASE_S)


def test_the_holds_of_an_older_database_get_one_default_lease(database_url: str) -> None:
    engine = create_database_engine(database_url)
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    with engine.begin() as connection:
        config.attributes["connection"] = connection
        command.upgrade(config, "0007")
        connection.execute(
            text(
                "INSERT INTO vehicle_holds (vehicle_id, username, since) VALUES ('URV1', 'a', :at)"
            ),
            {"at": datetime(2026, 11, 1, 12, 0, tzinfo=UTC)},
        )
    migrate(engine)
    with engine.connect() as connection:
        stored = connection.execute(text("SELECT expires_at FROM vehicle_holds")).scalar_one()
    expires = stored if isinstance(stored, datetime) else datetime.fromisoformat(stored)
    expires = expires if expires.tzinfo else expires.replace(tzinfo=UTC)
    assert timedelta(seconds=30) < expires - datetime.now(UTC) <= timedelta(seconds=60)
    with engine.begin() as connection:
        config.attributes["connection"] = connection
        command.downgrade(config, "0007")
    engine.dispose()
