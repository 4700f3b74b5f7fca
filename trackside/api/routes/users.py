"""Users: who may observe, drive or administer."""

from __future__ import annotations

from fastapi import APIRouter, status

from trackside.api.deps import AdminUser, CurrentUser, SessionDep
from trackside.api.schemas import UserCreate, UserPublic
from trackside.services import users

__all__ = ["router"]

router = APIRouter(prefix="/users", tags=["users"])


@router.get("/me")
def read_me(user: CurrentUser) -> UserPublic:
    """The signed-in user."""
    return UserPublic.from_user(user)


@router.post("", status_code=status.HTTP_201_CREATED)
def create_user(body: UserCreate, db: SessionDep, _admin: AdminUser) -> UserPublic:
    """Create a user (admin only)."""
    return UserPublic.from_user(users.create_user(db, body.username, body.password, body.role))
