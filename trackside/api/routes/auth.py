"""Bearer tokens: login (rate-limited) and logout (revocation), each audited.

Every login is audited, success or failure: the entry names the username tried (never the
password) and the client's address; a refused one says why (wrong credentials, a disabled user,
too many failures).
"""

from __future__ import annotations

import math
from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Request, Response, status
from fastapi.security import OAuth2PasswordRequestForm

from trackside.api.deps import AuditDep, CurrentUser, SessionDep, SettingsDep, TokenDep
from trackside.api.schemas import TokenPublic
from trackside.errors import AuthenticationError
from trackside.ratelimit import LoginLimiter
from trackside.services import users

__all__ = ["router"]

router = APIRouter(prefix="/auth", tags=["auth"])


@router.post(
    "/token",
    responses={
        401: {"description": "Wrong credentials, or a disabled user"},
        429: {"description": "Too many failed logins"},
    },
)
def login(
    request: Request,
    db: SessionDep,
    settings: SettingsDep,
    trail: AuditDep,
    form: Annotated[OAuth2PasswordRequestForm, Depends()],
) -> TokenPublic:
    """Exchange a username and password for a bearer token; 429 after too many failures."""
    limiter: LoginLimiter = request.app.state.login_limiter
    address = request.client.host if request.client is not None else "unknown"
    with trail.action(form.username, "login", request={"client": address}):
        wait_s = limiter.retry_after_s(form.username, address)
        if wait_s is not None:
            raise HTTPException(
                status_code=status.HTTP_429_TOO_MANY_REQUESTS,
                detail="too many failed logins; try again later",
                headers={"Retry-After": str(max(1, math.ceil(wait_s)))},
            )
        try:
            user = users.authenticate(db, form.username, form.password)
        except AuthenticationError:
            limiter.failed(form.username, address)  # counted; the app's handler answers 401
            raise
        limiter.succeeded(form.username)
        token = users.issue_token(db, user, settings.token_ttl_s)
    return TokenPublic(access_token=token)


@router.post("/logout", status_code=status.HTTP_204_NO_CONTENT)
def logout(db: SessionDep, token: TokenDep, user: CurrentUser, trail: AuditDep) -> Response:
    """Revoke the bearer token used for this request."""
    with trail.action(user.username, "logout"):
        users.revoke_token(db, token)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
