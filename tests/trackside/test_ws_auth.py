"""The WebSocket's token comes in its first message, never in the URL (issue 20)."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from tests.trackside.conftest import ADMIN, MakeClient, login
from trackside.api.routes import ws

pytestmark = pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)

STREAMS = ("/api/v1/ws/fleet", "/api/v1/ws/vehicles/URV1", "/api/v1/ws/session")


def _token(client: TestClient) -> str:
    return login(client, *ADMIN)["Authorization"].removeprefix("Bearer ")


def _closed_with(client: TestClient, path: str, *first: Any) -> int:
    """The close code of a socket to ``path`` after it sends ``first`` (JSON, or text)."""
    with client.websocket_connect(path) as socket:
        for message in first:
            if isinstance(message, str):
                socket.send_text(message)
            else:
                socket.send_json(message)
        with pytest.raises(WebSocketDisconnect) as closed:
            socket.receive_json()
    return closed.value.code


@pytest.mark.parametrize("path", STREAMS)
def test_the_token_in_the_first_message_opens_the_stream(client: TestClient, path: str) -> None:
    token = _token(client)
    with client.websocket_connect(path) as socket:
        socket.send_json({"type": "auth", "token": token})
        if path.endswith("/session"):
            assert socket.receive_json() == {"type": "holds", "holds": {}}
        elif path.endswith("/fleet"):
            assert socket.receive_json()["type"] == "fleet"


@pytest.mark.parametrize("path", STREAMS)
def test_a_token_in_the_url_is_refused(client: TestClient, path: str) -> None:
    token = _token(client)
    code = _closed_with(client, f"{path}?token={token}", {"type": "auth", "token": token})
    assert code == ws.POLICY_VIOLATION


@pytest.mark.parametrize(
    "first",
    [
        {"type": "auth", "token": "wrong"},
        {"type": "auth"},
        {"type": "subscribe", "token": "x"},
        ["auth"],
        "not json",
    ],
)
def test_a_bad_first_message_is_a_policy_violation(client: TestClient, first: Any) -> None:
    assert _closed_with(client, "/api/v1/ws/fleet", first) == ws.POLICY_VIOLATION


def test_no_first_message_in_time_is_a_policy_violation(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(ws, "AUTH_DEADLINE_S", 0.2)
    assert _closed_with(client, "/api/v1/ws/fleet") == ws.POLICY_VIOLATION


def test_a_revoked_token_closes_the_open_stream(make_client: MakeClient) -> None:
    client = make_client(hold_lease_s=0.6)  # the token is checked each third of a lease
    headers = login(client, *ADMIN)
    token = headers["Authorization"].removeprefix("Bearer ")
    with client.websocket_connect("/api/v1/ws/session") as socket:
        socket.send_json({"type": "auth", "token": token})
        assert socket.receive_json()["type"] == "holds"
        assert client.post("/api/v1/auth/logout", headers=headers).status_code == 204
        with pytest.raises(WebSocketDisconnect) as closed:
            socket.receive_json()  # nothing to push: the next frame is the close
    assert closed.value.code == ws.POLICY_VIOLATION
