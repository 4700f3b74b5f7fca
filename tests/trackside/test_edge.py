"""The web edge (issue 20): a body size limit before authentication, and security headers."""

from __future__ import annotations

from collections.abc import Iterator

from fastapi.testclient import TestClient

from tests.trackside.conftest import MakeClient, login

LIMIT = 4096


def test_a_body_over_the_limit_is_refused_before_authentication(make_client: MakeClient) -> None:
    client = make_client(max_body_bytes=LIMIT)
    # No credentials at all: the size is judged first (a 401 would mean the body was read).
    response = client.post(
        "/api/v1/journeys", content=b"x" * (LIMIT + 1), headers={"content-type": "application/json"}
    )
    assert response.status_code == 413
    assert response.headers["x-content-type-options"] == "nosniff"


def test_a_chunked_body_over_the_limit_is_cut_off(make_client: MakeClient) -> None:
    client = make_client(max_body_bytes=LIMIT)

    def chunks() -> Iterator[bytes]:
        for _ in range(8):
            yield b"x" * 1024

    response = client.post(
        "/api/v1/journeys", content=chunks(), headers={"content-type": "application/json"}
    )
    assert "content-length" not in response.request.headers
    assert response.status_code == 413


def test_a_body_under_the_limit_goes_through(make_client: MakeClient) -> None:
    client = make_client(max_body_bytes=LIMIT)
    response = client.post(
        "/api/v1/auth/token", data={"username": "root", "password": "wrong-password"}
    )
    assert response.status_code == 401


def test_every_response_carries_the_security_headers(client: TestClient) -> None:
    headers = login(client, "root", "admin-password")
    api = client.get("/api/v1/vehicles", headers=headers)
    page = client.get("/")
    for response in (api, page):
        assert response.headers["x-frame-options"] == "DENY"
        assert response.headers["referrer-policy"] == "no-referrer"
        assert response.headers["x-content-type-options"] == "nosniff"
    assert api.headers["cache-control"] == "no-store"
