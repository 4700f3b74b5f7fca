"""Users: who may observe, drive or administer."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, status
from pydantic import BaseModel, Field

from trackside.api.deps import AdminUser, CurrentUser, SessionDep
from trackside.errors import ConflictError
from trackside.models import Role, User
from trackside.services import users

router = APIRouter(prefix="/users", tags=["users"])


class UserCreate(BaseModel):
    username: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")
    password: str = Field(min_length=8, max_length=256)
    role: Role


class UserPublic(BaseModel):
    username: str
    role: Role

    @classmethod
    def from_user(cls, user: User) -> UserPublic:
        return cls(username=user.username, role=Role(user.role))


@router.get("/me")
def read_me(user: CurrentUser) -> UserPublic:
    """The signed-in user."""
    return UserPublic.from_user(user)


@router.post("", status_code=status.HTTP_201_CREATED)
def create_user(body: UserCreate, db: SessionDep, _admin: AdminUser) -> UserPublic:
    """Create a user (admin only)."""
    try:
        user = users.create_user(db, body.username, body.password, body.role)
    except ConflictError as exc:
        raise HTTPException(status_code=status.HTTP_409_CONFLICT, detail=str(exc)) from exc
    return UserPublic.from_user(user)
