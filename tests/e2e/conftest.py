"""The trackside service of the end-to-end tests: real app, SQLite file, on the test's router."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from trackside.config import Settings
from trackside.main import create_app

ADMIN = ("admin", "e2e-password")


@contextmanager
def running_trackside(
    router_endpoint: str, tmp_path: Path
) -> Iterator[tuple[TestClient, dict[str, str]]]:
    """The service with an admin account, and the admin's bearer header."""
    settings = Settings(
        database_url=f"sqlite:///{tmp_path / 'ts.db'}",
        zenoh_connect=(router_endpoint,),
        admin_user=ADMIN[0],
        admin_password=ADMIN[1],
        # The admin's hold must outlast a restart and a loaded machine's minute between two
        # commands: these tests are not about leases (tests/trackside/test_hold_leases.py).
        hold_lease_s=600.0,
    )
    with TestClient(create_app(settings)) as client:
        response = client.post(
            "/api/v1/auth/token", data=dict(zip(("username", "password"), ADMIN, strict=True))
        )
        yield client, {"Authorization": f"Bearer {response.json()['access_token']}"}


@pytest.fixture
def trackside(router_endpoint: str, tmp_path: Path) -> Iterator[tuple[TestClient, dict[str, str]]]:
    with running_trackside(router_endpoint, tmp_path) as service:
        yield service
