"""Bearer tokens."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, status
from fastapi.security import OAuth2PasswordRequestForm

from trackside.api.deps import SessionDep, SettingsDep
from trackside.api.schemas import TokenPublic
from trackside.errors import AuthenticationError
from trackside.services import users

router = APIRouter(prefix="/auth", tags=["auth"])


@router.post("/token")
def login(
    db: SessionDep,
    settings: SettingsDep,
    form: Annotated[OAuth2PasswordRequestForm, Depends()],
) -> TokenPublic:
    """Exchange a username and password for a bearer token."""
    try:
        user = users.authenticate(db, form.username, form.password)
    except AuthenticationError as exc:
        raise HTTPException(
            status_code=status.HTTP_401_UNAUTHORIZED,
            detail="wrong username or password",
            headers={"WWW-Authenticate": "Bearer"},
        ) from exc
    return TokenPublic(access_token=users.issue_token(db, user, settings.token_ttl_s))
