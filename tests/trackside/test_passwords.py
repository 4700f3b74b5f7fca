"""Password hashes at OWASP's scrypt cost (issue 20): the hash names its cost, an older hash
still verifies, and a login upgrades it in place."""

from __future__ import annotations

import time

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import text

from tests.trackside.conftest import ADMIN, MakeClient, login
from trackside.db import create_database_engine
from trackside.security import (
    LEGACY_COST,
    OWASP_COST,
    ScryptCost,
    hash_password,
    needs_rehash,
    password_cost,
    use_password_cost,
    verify_password,
)
from trackside.services import users


def _cost_of(stored: str) -> ScryptCost:
    _, n, r, p, _, _ = stored.split("$")
    return ScryptCost(n=int(n), r=int(r), p=int(p))


def test_a_new_hash_is_at_owasps_cost_and_says_so() -> None:
    assert (OWASP_COST.n, OWASP_COST.r, OWASP_COST.p) == (2**17, 8, 1)
    assert OWASP_COST.memory_bytes > 128 * 1024 * 1024  # hashlib's default maxmem is 32 MiB
    with use_password_cost(OWASP_COST):
        started = time.perf_counter()
        stored = hash_password("correct horse")
        hashing_s = time.perf_counter() - started
        assert stored.startswith("scrypt$131072$8$1$")
        assert verify_password("correct horse", stored)
        assert not verify_password("correct horse!", stored)
        assert not needs_rehash(stored)
    # The cost is real: far above the legacy hash's (about 8 times the work).
    assert hashing_s > 0.05


def test_an_unknown_users_password_is_checked_at_owasps_cost_too() -> None:
    """The hash an unknown username's password is checked against (so that it costs what a
    known one's does) is a valid hash at today's cost, written in the code, not made at import."""
    assert _cost_of(users._DUMMY_HASH) == OWASP_COST
    with use_password_cost(OWASP_COST):
        assert not needs_rehash(users._DUMMY_HASH)
    assert not verify_password("timing-equaliser", users._DUMMY_HASH)


def test_an_older_hash_verifies_at_its_own_cost_and_asks_to_be_renewed() -> None:
    with use_password_cost(LEGACY_COST):
        legacy = hash_password("pw-of-2025")
    assert _cost_of(legacy) == LEGACY_COST
    with use_password_cost(OWASP_COST):
        assert verify_password("pw-of-2025", legacy)
        assert needs_rehash(legacy)


@pytest.mark.parametrize(
    "stored",
    [
        "scrypt$1073741824$8$1$c2FsdA==$ZGlnZXN0",  # N = 2^30: 1 TiB, refused unread
        "scrypt$131072$64$1$c2FsdA==$ZGlnZXN0",  # r too large (1 GiB)
        "scrypt$100000$8$1$c2FsdA==$ZGlnZXN0",  # N not a power of two
        "bcrypt$16384$8$1$c2FsdA==$ZGlnZXN0",
        "scrypt$16384$8$1$c2FsdA==",
        "",
    ],
)
def test_a_hash_of_no_acceptable_cost_verifies_nothing(stored: str) -> None:
    started = time.perf_counter()
    assert not verify_password("pw", stored)
    assert time.perf_counter() - started < 0.5
    assert needs_rehash(stored)


@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_a_login_upgrades_an_older_hash_in_place(
    make_client: MakeClient, database_url: str
) -> None:
    client: TestClient = make_client()
    admin = login(client, *ADMIN)
    body = {"username": "carol", "password": "carol-password", "role": "driver"}
    with use_password_cost(LEGACY_COST):
        assert client.post("/api/v1/users", json=body, headers=admin).status_code == 201
    engine = create_database_engine(database_url)

    def stored() -> str:
        with engine.connect() as connection:
            query = text("SELECT password_hash FROM users WHERE username = 'carol'")
            return str(connection.execute(query).scalar_one())

    assert _cost_of(stored()) == LEGACY_COST
    wrong = client.post("/api/v1/auth/token", data={"username": "carol", "password": "nope"})
    assert wrong.status_code == 401
    assert _cost_of(stored()) == LEGACY_COST  # only a successful login renews the hash
    login(client, "carol", "carol-password")
    assert _cost_of(stored()) == password_cost()
    login(client, "carol", "carol-password")  # and the new hash verifies
    engine.dispose()
