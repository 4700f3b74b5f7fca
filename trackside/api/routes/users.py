"""Users: who may observe, drive or administer; an admin creates, disables and enables users
and resets passwords. Every change is audited."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Path, status

from trackside.api.deps import AdminUser, AuditDep, CurrentUser, SessionDep
from trackside.api.schemas import PasswordReset, UserCreate, UserPublic
from trackside.services import users

__all__ = ["router"]

router = APIRouter(prefix="/users", tags=["users"])

UsernamePath = Annotated[
    str, Path(min_length=1, max_length=64, description="Username", examples=["alice"])
]
NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"description": "No such user"}}


@router.get("/me")
def read_me(user: CurrentUser) -> UserPublic:
    """The signed-in user."""
    return UserPublic.from_user(user)


@router.post("", status_code=status.HTTP_201_CREATED)
def create_user(body: UserCreate, db: SessionDep, admin: AdminUser, trail: AuditDep) -> UserPublic:
    """Create a user (admin only)."""
    request = {"username": body.username, "role": body.role.value}
    with trail.action(admin.username, "user.create", request=request):
        user = users.create_user(db, body.username, body.password, body.role)
    return UserPublic.from_user(user)


@router.post(
    "/{username}/disable",
    responses={**NOT_FOUND, 409: {"description": "An admin cannot disable themself"}},
)
def disable_user(
    username: UsernamePath, db: SessionDep, admin: AdminUser, trail: AuditDep
) -> UserPublic:
    """Disable a user (admin only): they cannot log in, and their tokens stop working at once."""
    with trail.action(admin.username, "user.disable", request={"username": username}):
        user = users.set_disabled(db, admin, username, disabled=True)
    return UserPublic.from_user(user)


@router.post("/{username}/enable", responses=NOT_FOUND)
def enable_user(
    username: UsernamePath, db: SessionDep, admin: AdminUser, trail: AuditDep
) -> UserPublic:
    """Enable a disabled user again (admin only); their old tokens stay revoked."""
    with trail.action(admin.username, "user.enable", request={"username": username}):
        user = users.set_disabled(db, admin, username, disabled=False)
    return UserPublic.from_user(user)


@router.post("/{username}/password", responses=NOT_FOUND)
def reset_password(
    username: UsernamePath,
    body: PasswordReset,
    db: SessionDep,
    admin: AdminUser,
    trail: AuditDep,
) -> UserPublic:
    """Set a user's new password (admin only) and revoke their tokens."""
    # The audit entry names the user, never the password.
    with trail.action(admin.username, "user.password", request={"username": username}):
        user = users.reset_password(db, username, body.password)
    return UserPublic.from_user(user)
