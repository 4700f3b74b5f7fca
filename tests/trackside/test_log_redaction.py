"""Bearer tokens never appear in a log record (issue 20): the service under uvicorn, its access
log on, through a login, authenticated requests, WebSocket sessions and a token put in URLs."""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest
import uvicorn
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

from deploy.ports import free_tcp_port
from tests.conftest import wait_for
from tests.trackside.conftest import ADMIN
from trackside.config import Settings
from trackside.log_redaction import (
    REDACTED,
    REQUEST_LOGGERS,
    TokenRedactingFilter,
    redact_tokens,
)
from trackside.main import create_app

TOKEN = "Zm9vYmFy-token_with.all~chars+/="


@pytest.mark.parametrize(
    "text",
    [
        f"Authorization: Bearer {TOKEN}",
        f'"GET /api/v1/ws/fleet?token={TOKEN}&x=1 HTTP/1.1" 200',
        f"grant_type=password&access_token={TOKEN}",
        f'{{"access_token": "{TOKEN}", "token_type": "bearer"}}',
        f"{{'type': 'auth', 'token': '{TOKEN}'}}",
    ],
)
def test_the_token_is_blanked_out_of_text(text: str) -> None:
    redacted = redact_tokens(text)
    assert "Zm9vYmFy" not in redacted
    assert REDACTED in redacted


def test_the_filter_keeps_the_shape_of_uvicorn_access_records() -> None:
    record = logging.LogRecord(
        "uvicorn.access",
        logging.INFO,
        __file__,
        1,
        '%s - "%s %s HTTP/%s" %d',
        ("127.0.0.1:5000", "GET", f"/api/v1/vehicles?token={TOKEN}", "1.1", 401),
        None,
    )
    assert TokenRedactingFilter().filter(record)
    assert isinstance(record.args, tuple)
    assert len(record.args) == 5  # uvicorn's access formatter unpacks five
    assert record.getMessage() == (
        f'127.0.0.1:5000 - "GET /api/v1/vehicles?token={REDACTED} HTTP/1.1" 401'
    )


def test_a_token_split_between_format_and_argument_is_blanked_out() -> None:
    record = logging.LogRecord("x", logging.INFO, __file__, 1, "Bearer %s", (TOKEN,), None)
    TokenRedactingFilter().filter(record)
    assert record.getMessage() == f"Bearer {REDACTED}"


@contextmanager
def _served(settings: Settings) -> Iterator[str]:
    """The service under uvicorn in a thread, with uvicorn's own logging (access log on)."""
    port = free_tcp_port()
    config = uvicorn.Config(create_app(settings), host="127.0.0.1", port=port, log_level="info")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    assert wait_for(lambda: server.started, 10.0)
    try:
        yield f"127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(10.0)


@contextmanager
def _capturing(handler: logging.Handler) -> Iterator[None]:
    """uvicorn's loggers do not propagate to the root: hand their records to ``handler``."""
    loggers = [logging.getLogger(name) for name in REQUEST_LOGGERS]
    for logger in loggers:
        logger.addHandler(handler)
    try:
        yield
    finally:
        for logger in loggers:
            logger.removeHandler(handler)


def _session(address: str, token: str) -> None:
    """A WebSocket session as the console opens it, then one with the token in the URL."""
    with connect(f"ws://{address}/api/v1/ws/session") as socket:
        socket.send(f'{{"type": "auth", "token": "{token}"}}')
        assert '"holds"' in str(socket.recv(timeout=5.0))
    with connect(f"ws://{address}/api/v1/ws/fleet?token={token}") as socket:
        with pytest.raises(ConnectionClosed) as closed:
            socket.recv(timeout=5.0)
        assert closed.value.rcvd is not None
        assert closed.value.rcvd.code == 1008
    with pytest.raises((ConnectionClosed, InvalidStatus)):  # an unknown path: refused
        connect(f"ws://{address}/api/v1/ws/nowhere?token={token}").recv(timeout=5.0)


def test_no_token_reaches_a_log_record(
    router_endpoint: str, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    settings = Settings(
        database_url=f"sqlite:///{tmp_path / 'ts.db'}",
        zenoh_connect=(router_endpoint,),
        admin_user=ADMIN[0],
        admin_password=ADMIN[1],
    )
    caplog.set_level(logging.DEBUG)
    with _served(settings) as address, _capturing(caplog.handler):
        base = f"http://{address}"
        login = httpx.post(
            f"{base}/api/v1/auth/token", data={"username": ADMIN[0], "password": ADMIN[1]}
        )
        token = login.json()["access_token"]
        bearer = {"Authorization": f"Bearer {token}"}
        assert httpx.get(f"{base}/api/v1/vehicles", headers=bearer).status_code == 200
        assert httpx.get(f"{base}/api/v1/vehicles?token={token}").status_code == 401
        assert httpx.get(f"{base}/api/v1/audit?access_token={token}", headers=bearer).is_success
        bad = {"Authorization": f"Bearer {token}x"}
        assert httpx.get(f"{base}/api/v1/vehicles", headers=bad).status_code == 401
        _session(address, token)
        assert httpx.post(f"{base}/api/v1/auth/logout", headers=bearer).status_code == 204
    messages = [record.getMessage() for record in caplog.records]
    assert any("/api/v1/vehicles?token=" in message for message in messages), messages
    assert any("WebSocket /api/v1/ws/session" in message for message in messages), messages
    leaked = [
        message
        for record, message in zip(caplog.records, messages, strict=True)
        if token in message or token in (record.exc_text or "")
    ]
    assert not leaked
    assert token not in caplog.text
