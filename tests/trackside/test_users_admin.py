"""Admin routes on users, and the audit of logins (issue 20), on SQLite and PostgreSQL: a
disabled user cannot log in and their tokens stop at once; a password reset revokes the tokens;
every login, success or failure, is audited, never with the password."""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient

from tests.trackside.conftest import ADMIN, login

USERS = "/api/v1/users"


def _create(client: TestClient, admin: dict[str, str], username: str, password: str) -> None:
    body = {"username": username, "password": password, "role": "driver"}
    assert client.post(USERS, json=body, headers=admin).status_code == 201


def _token_login(client: TestClient, username: str, password: str) -> Any:
    return client.post("/api/v1/auth/token", data={"username": username, "password": password})


def _audit(client: TestClient, admin: dict[str, str]) -> list[dict[str, Any]]:
    return list(client.get("/api/v1/audit", params={"limit": 1000}, headers=admin).json())


def test_a_disabled_user_cannot_log_in_and_their_tokens_stop_at_once(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    _create(client, admin_headers, "dora", "dora-password")
    dora = login(client, "dora", "dora-password")
    assert client.get(f"{USERS}/me", headers=dora).status_code == 200
    disabled = client.post(f"{USERS}/dora/disable", headers=admin_headers)
    assert disabled.status_code == 200
    assert disabled.json() == {"username": "dora", "role": "driver", "disabled": True}
    assert client.get(f"{USERS}/me", headers=dora).status_code == 401
    refused = _token_login(client, "dora", "dora-password")
    assert refused.status_code == 401
    assert refused.json() == {"detail": "user 'dora' is disabled"}
    # A wrong password does not learn that the user is disabled.
    wrong = _token_login(client, "dora", "not-her-password")
    assert wrong.json() == {"detail": "wrong username or password"}
    enabled = client.post(f"{USERS}/dora/enable", headers=admin_headers)
    assert enabled.json()["disabled"] is False
    assert client.get(f"{USERS}/me", headers=dora).status_code == 401  # old tokens stay revoked
    assert (
        client.get(f"{USERS}/me", headers=login(client, "dora", "dora-password")).status_code == 200
    )


def test_an_admin_cannot_disable_themself_and_unknown_users_are_404(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    own = client.post(f"{USERS}/{ADMIN[0]}/disable", headers=admin_headers)
    assert own.status_code == 409
    assert client.get(f"{USERS}/me", headers=admin_headers).status_code == 200
    for action in ("disable", "enable"):
        assert client.post(f"{USERS}/nobody/{action}", headers=admin_headers).status_code == 404
    reset = client.post(
        f"{USERS}/nobody/password", json={"password": "long-enough"}, headers=admin_headers
    )
    assert reset.status_code == 404


def test_a_password_reset_revokes_the_tokens(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    _create(client, admin_headers, "pete", "pete-password")
    pete = login(client, "pete", "pete-password")
    too_short = client.post(
        f"{USERS}/pete/password", json={"password": "short"}, headers=admin_headers
    )
    assert too_short.status_code == 422
    reset = client.post(
        f"{USERS}/pete/password", json={"password": "new-pete-password"}, headers=admin_headers
    )
    assert reset.status_code == 200
    assert client.get(f"{USERS}/me", headers=pete).status_code == 401
    assert _token_login(client, "pete", "pete-password").status_code == 401
    assert (
        client.get(f"{USERS}/me", headers=login(client, "pete", "new-pete-password")).status_code
        == 200
    )
    entries = [e for e in _audit(client, admin_headers) if e["action"] == "user.password"]
    assert [(e["user"], e["request"], e["result"]) for e in entries] == [
        (ADMIN[0], {"username": "pete"}, "accepted")
    ]
    assert "new-pete-password" not in str(_audit(client, admin_headers))


def test_only_an_admin_manages_users(client: TestClient, admin_headers: dict[str, str]) -> None:
    _create(client, admin_headers, "dan", "dan-password")
    dan = login(client, "dan", "dan-password")
    for action, body in (("disable", None), ("enable", None), ("password", {"password": "x" * 9})):
        response = client.post(f"{USERS}/{ADMIN[0]}/{action}", json=body, headers=dan)
        assert response.status_code == 403, action


def test_every_login_is_audited_without_the_password(
    client: TestClient, admin_headers: dict[str, str]
) -> None:
    assert _token_login(client, ADMIN[0], "a-wrong-secret").status_code == 401
    assert _token_login(client, "nobody", "another-secret").status_code == 401
    login(client, *ADMIN)
    logins = [e for e in _audit(client, admin_headers) if e["action"] == "login"]
    # The fixture's own login first, then the three above.
    assert [(e["user"], e["result"], e["detail"]) for e in logins] == [
        (ADMIN[0], "accepted", None),
        (ADMIN[0], "refused", "wrong username or password"),
        ("nobody", "refused", "wrong username or password"),
        (ADMIN[0], "accepted", None),
    ]
    assert all(e["request"] == {"client": "testclient"} and e["vehicle_id"] is None for e in logins)
    text = str(_audit(client, admin_headers))
    assert "a-wrong-secret" not in text
    assert "another-secret" not in text
    assert ADMIN[1] not in text


def test_a_rate_limited_login_is_audited(make_client: Any) -> None:
    client = make_client(login_max_failures=2)
    admin = login(client, *ADMIN)  # before the failures lock this client's address out
    for _ in range(2):
        assert _token_login(client, "eve", "guess").status_code == 401
    assert _token_login(client, "eve", "guess").status_code == 429
    logins = [e for e in _audit(client, admin) if e["user"] == "eve"]
    assert [e["result"] for e in logins] == ["refused"] * 3
    assert logins[-1]["detail"] == "too many failed logins; try again later"


def test_a_logout_is_audited(client: TestClient, admin_headers: dict[str, str]) -> None:
    assert client.post("/api/v1/auth/logout", headers=admin_headers).status_code == 204
    admin = login(client, *ADMIN)
    entries = [e for e in _audit(client, admin) if e["action"] == "logout"]
    assert [(e["user"], e["result"]) for e in entries] == [(ADMIN[0], "accepted")]
