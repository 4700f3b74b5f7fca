"""Dependencies shared by the routes: database session, current user, role checks, bridge.

A token that does not resolve or a role too low raises the services' domain error; the app's
exception handlers answer it (401, 403), as for the routes.
"""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable, Coroutine
from typing import Annotated, Any

import anyio
import anyio.to_thread
from fastapi import Depends, Request
from fastapi.security import OAuth2PasswordBearer
from sqlalchemy.orm import Session, sessionmaker

from trackside.api.audit_trail import AuditTrail, audit_trail
from trackside.bridge import ZenohBridge
from trackside.config import Settings
from trackside.models import Role, User
from trackside.services import users
from trackside.services.commands import CommandService
from trackside.simulated_operator import SimulatedOperatorThread

__all__ = [
    "AdminUser",
    "AuditDep",
    "BridgeDep",
    "CommandsDep",
    "SimulatedDep",
    "TokenDep",
    "DriverUser",
    "CurrentUser",
    "SessionDep",
    "ObserverUser",
    "SettingsDep",
    "require",
]

oauth2_scheme = OAuth2PasswordBearer(tokenUrl="/api/v1/auth/token")


AuditDep = Annotated[AuditTrail, Depends(audit_trail, scope="function")]
"""The request's audit trail; closed (its entries written) after the request's transaction."""


async def get_db(request: Request, _trail: AuditDep) -> AsyncIterator[Session]:
    """One transaction per request, committed when the route function returns (``scope=
    "function"`` below), so before the answer leaves: a client that sends its next request as
    soon as it reads the answer (the console right after sign-in) sees what was written. It
    depends on the audit trail so that the trail is closed after the transaction has ended.

    The session is made on the event loop (its connection is taken at its first statement, in
    the route's thread) and ended in the thread pool, shielded from the request's cancellation:
    one trip to the pool for the commit, not one more for the opening."""
    factory: sessionmaker[Session] = request.app.state.session_factory
    db = factory()
    db.begin()
    committing = False
    try:
        yield db
        committing = True
    finally:
        with anyio.CancelScope(shield=True):
            await anyio.to_thread.run_sync(_end, db, committing)


def _end(db: Session, commit: bool) -> None:
    """Commit (or roll back) the request's transaction and give its connection back."""
    try:
        if commit:
            db.commit()
        else:
            db.rollback()
    finally:
        db.close()


async def get_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


async def get_bridge(request: Request) -> ZenohBridge:
    bridge: ZenohBridge = request.app.state.bridge
    return bridge


async def get_commands(request: Request) -> CommandService:
    commands: CommandService = request.app.state.commands
    return commands


async def simulated_vehicles(request: Request) -> frozenset[str]:
    """The vehicles the simulated operator answers."""
    operator: SimulatedOperatorThread | None = request.app.state.simulated_operator
    return frozenset() if operator is None else operator.operator.vehicles


SessionDep = Annotated[Session, Depends(get_db, scope="function")]
CommandsDep = Annotated[CommandService, Depends(get_commands)]
SimulatedDep = Annotated[frozenset[str], Depends(simulated_vehicles)]
SettingsDep = Annotated[Settings, Depends(get_settings)]
BridgeDep = Annotated[ZenohBridge, Depends(get_bridge)]
TokenDep = Annotated[str, Depends(oauth2_scheme)]


def get_current_user(db: SessionDep, token: TokenDep) -> User:
    """The user of the request's bearer token; 401 when it is not a valid one."""
    return users.resolve_token(db, token)


CurrentUser = Annotated[User, Depends(get_current_user)]


def require(role: Role) -> Callable[[User], Coroutine[Any, Any, User]]:
    """A dependency that lets through users with at least ``role``; others get 403. Pure
    dependencies are ``async`` so that they run on the event loop, not in a worker thread."""

    async def check(user: CurrentUser) -> User:
        users.require_role(user, role)
        return user

    return check


ObserverUser = Annotated[User, Depends(require(Role.OBSERVER))]
DriverUser = Annotated[User, Depends(require(Role.DRIVER))]
AdminUser = Annotated[User, Depends(require(Role.ADMIN))]
