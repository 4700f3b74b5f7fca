"""The web edge (issue 20): a body size limit before authentication, and security headers."""

from __future__ import annotations

import re
from collections.abc import Iterator

from fastapi.testclient import TestClient

from tests.trackside.conftest import MakeClient, login
from trackside.config import DEFAULT_WEBUI_DIR
from trackside.edge import EMPTY_STYLE_HASH

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


def test_the_console_and_the_api_carry_the_content_security_policy(client: TestClient) -> None:
    headers = login(client, "root", "admin-password")
    responses = [
        client.get("/"),
        client.get("/static/app.js"),
        client.get("/api/v1/vehicles", headers=headers),
        client.post("/api/v1/journeys", content=b"x" * (9 * 1024 * 1024)),  # 413 at the edge
    ]
    policies = {response.headers["content-security-policy"] for response in responses}
    assert len(policies) == 1
    policy = {
        directive.split()[0]: directive.split()[1:] for directive in policies.pop().split(";")
    }
    assert policy["script-src"] == ["'self'"]  # no inline script at all
    # Inline styles: only plotly's, by hash (its empty sheet and its bundled map stylesheet).
    assert policy["style-src"][:2] == ["'self'", EMPTY_STYLE_HASH]
    assert all(source.startswith("'sha256-") for source in policy["style-src"][1:])
    assert policy["connect-src"] == policy["default-src"] == ["'self'"]
    assert policy["frame-ancestors"] == policy["object-src"] == ["'none'"]
    # FastAPI's API documentation loads Swagger UI from a CDN with an inline script.
    assert "content-security-policy" not in client.get("/docs").headers
    assert client.get("/docs").headers["x-frame-options"] == "DENY"


def test_the_console_has_no_inline_script_style_or_handler() -> None:
    html = (DEFAULT_WEBUI_DIR / "index.html").read_text()
    assert not re.search(r"<script(?![^>]*\bsrc=)[^>]*>", html)  # every script from a file
    assert "<style" not in html
    assert not re.search(r"\sstyle=", html)
    assert not re.search(r"\son[a-z]+=", html)
