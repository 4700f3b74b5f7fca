"""Dependencies shared by the routes: database session, current user, role checks, bridge."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Annotated

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import OAuth2PasswordBearer
from sqlalchemy.orm import Session, sessionmaker

from trackside.bridge import ZenohBridge
from trackside.config import Settings
from trackside.errors import AuthenticationError, PermissionDeniedError
from trackside.models import Role, User
from trackside.services import users

__all__ = [
    "AdminUser",
    "BridgeDep",
    "DriverUser",
    "CurrentUser",
    "SessionDep",
    "ObserverUser",
    "SettingsDep",
    "require",
]

oauth2_scheme = OAuth2PasswordBearer(tokenUrl="/api/v1/auth/token")


def get_db(request: Request) -> Iterator[Session]:
    factory: sessionmaker[Session] = request.app.state.session_factory
    with factory() as db, db.begin():
        yield db


def get_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


def get_bridge(request: Request) -> ZenohBridge:
    bridge: ZenohBridge = request.app.state.bridge
    return bridge


SessionDep = Annotated[Session, Depends(get_db)]
SettingsDep = Annotated[Settings, Depends(get_settings)]
BridgeDep = Annotated[ZenohBridge, Depends(get_bridge)]
TokenDep = Annotated[str, Depends(oauth2_scheme)]

UNAUTHORISED = HTTPException(
    status_code=status.HTTP_401_UNAUTHORIZED,
    detail="not authenticated",
    headers={"WWW-Authenticate": "Bearer"},
)


def get_current_user(db: SessionDep, token: TokenDep) -> User:
    try:
        return users.resolve_token(db, token)
    except AuthenticationError as exc:
        raise UNAUTHORISED from exc


CurrentUser = Annotated[User, Depends(get_current_user)]


def require(role: Role) -> Callable[[User], User]:
    """A dependency that lets through users with at least ``role``; others get 403."""

    def check(user: CurrentUser) -> User:
        try:
            users.require_role(user, role)
        except PermissionDeniedError as exc:
            raise HTTPException(status_code=status.HTTP_403_FORBIDDEN, detail=str(exc)) from exc
        return user

    return check


ObserverUser = Annotated[User, Depends(require(Role.OBSERVER))]
DriverUser = Annotated[User, Depends(require(Role.DRIVER))]
AdminUser = Annotated[User, Depends(require(Role.ADMIN))]
