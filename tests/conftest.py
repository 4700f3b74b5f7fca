"""Shared fixtures: loopback Zenoh sessions and routers, databases (SQLite and PostgreSQL)."""

from __future__ import annotations

import os
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest
import zenoh
from hypothesis import settings
from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url

from deploy.ports import loopback_endpoint
from protocol import ZenohSettings, open_session
from protocol.router import run_router
from trackside.security import ScryptCost, use_password_cost

WAIT_S = 5.0
TEST_PASSWORD_COST = ScryptCost(n=2**10, r=8, p=1)
"""The scrypt cost of the passwords the suite hashes (1 MiB, about 2 ms): at the service's own
(N = 2^17, 0.4-0.7 s a hash here) its few hundred users and logins would take minutes
(docs/security.md). tests/trackside/test_passwords.py hashes at the real cost."""

# No wall-clock deadline on hypothesis examples: the suite asserts behaviour, not speed, and a
# loaded machine (CI, a campaign alongside) makes a 200 ms deadline fail at random. The inner
# loop (`make check`) draws fewer examples; `make test` and CI draw the full number.
settings.register_profile("ato", deadline=None)
settings.register_profile("ato-quick", deadline=None, max_examples=15)
settings.load_profile(os.environ.get("ATO_HYPOTHESIS_PROFILE", "ato"))


def wait_for(
    predicate: Callable[[], bool], timeout_s: float = WAIT_S, step_s: float = 0.01
) -> bool:
    """Poll ``predicate`` until it holds or the timeout passes; returns whether it held."""
    deadline = time.monotonic() + timeout_s
    idle = threading.Event()
    while time.monotonic() < deadline:
        if predicate():
            return True
        idle.wait(step_s)
    return predicate()


@pytest.fixture(autouse=True, scope="session")
def cheap_password_hashes() -> Iterator[None]:
    """Hash the suite's passwords at :data:`TEST_PASSWORD_COST` (test-only)."""
    with use_password_cost(TEST_PASSWORD_COST):
        yield


@pytest.fixture
def zenoh_pair() -> Iterator[tuple[zenoh.Session, zenoh.Session]]:
    """Two peer sessions in this process, the second connected to the first over loopback."""
    endpoint = loopback_endpoint()
    with (
        open_session(ZenohSettings(mode="peer", connect=(), listen=(endpoint,))) as first,
        open_session(ZenohSettings(mode="peer", connect=(endpoint,))) as second,
    ):
        assert wait_for(lambda: bool(first.info.peers_zid()))
        yield first, second


@contextmanager
def running_router() -> Iterator[str]:
    """A Zenoh router running in this process on a free loopback port, until the block ends."""
    endpoint = loopback_endpoint()
    stop, ready = threading.Event(), threading.Event()
    thread = threading.Thread(
        target=run_router, args=(stop,), kwargs={"listen": [endpoint], "ready": ready}, daemon=True
    )
    thread.start()
    assert ready.wait(WAIT_S)
    yield endpoint
    stop.set()
    thread.join(WAIT_S)


@pytest.fixture
def router_endpoint() -> Iterator[str]:
    """A Zenoh router running in this process on a free loopback port."""
    with running_router() as endpoint:
        yield endpoint


def _postgres_database() -> Iterator[str]:
    base = os.environ.get("ATO_TEST_DATABASE_URL")
    if not base:
        pytest.skip("ATO_TEST_DATABASE_URL not set: no PostgreSQL for this run")
    # A fresh schema per test keeps tests independent on one shared server.
    schema = f"t_{uuid.uuid4().hex[:12]}"
    admin = create_engine(base)
    with admin.begin() as connection:
        connection.execute(text(f'CREATE SCHEMA "{schema}"'))
    url = make_url(base).update_query_dict({"options": f"-csearch_path={schema}"})
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with admin.begin() as connection:
            connection.execute(text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def database_url(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[str]:
    """A database URL for each backend: an SQLite file, and PostgreSQL when configured."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path_factory.mktemp('db') / 'ato.db'}"
    else:
        yield from _postgres_database()
