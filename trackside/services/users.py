"""Users, roles and bearer tokens; an admin disables users and resets passwords.

A disabled user cannot log in, and their tokens are refused at once: :func:`resolve_token` reads
the user on every request. Disabling also revokes their tokens, as does a password reset, so
that enabling the user again does not bring the old tokens back.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from sqlalchemy import select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from trackside.errors import (
    AuthenticationError,
    ConflictError,
    InvalidTokenError,
    NotFoundError,
    PermissionDeniedError,
)
from trackside.models import ApiToken, Role, User
from trackside.security import (
    hash_password,
    needs_rehash,
    new_token,
    token_digest,
    verify_password,
)

__all__ = [
    "authenticate",
    "create_user",
    "ensure_token_user",
    "ensure_user",
    "get_user",
    "issue_token",
    "require_role",
    "reset_password",
    "resolve_token",
    "revoke_token",
    "revoke_tokens_of",
    "set_disabled",
]


_DUMMY_HASH = (
    "scrypt$131072$8$1$Km-ZEJj36a87oi3v5z7JQQ==$3CTuOJZXKQiGcYcLbg0DdIkk-yOPLXXQYAFBpxDZ8L0="
)
"""What an unknown user's password is checked against, so that a wrong username costs what a
wrong password does: the hash, at today's cost, of a random password nobody kept (written here
rather than made at import, which cost half a second of scrypt in every process)."""


NO_PASSWORD = "!"
"""The password hash of a user who has none (:func:`ensure_token_user`): no hash of ours, so no
password matches it."""


def _now() -> datetime:
    return datetime.now(UTC)


def _check_password(password: str) -> None:
    if len(password) < 4:
        raise ValueError("password must have at least 4 characters")


def _check_username(username: str) -> None:
    if not username or len(username) > 64:
        raise ValueError("username must have 1 to 64 characters")


def _add_user(db: Session, username: str, password_hash: str, role: Role) -> User:
    """A new user (``password_hash`` made or :data:`NO_PASSWORD`); a taken name is a conflict."""
    user = User(username=username, password_hash=password_hash, role=role.value, created_at=_now())
    db.add(user)
    try:
        db.flush()
    except IntegrityError as exc:
        db.rollback()
        raise ConflictError(f"user {username!r} exists") from exc
    return user


def create_user(db: Session, username: str, password: str, role: Role) -> User:
    _check_username(username)
    _check_password(password)
    return _add_user(db, username, hash_password(password), role)


def ensure_user(db: Session, username: str, password: str, role: Role) -> User:
    """The user of that name, created with this password and role if missing."""
    existing = db.scalar(select(User).where(User.username == username))
    return existing if existing is not None else create_user(db, username, password, role)


def ensure_token_user(db: Session, username: str, role: Role) -> User:
    """The user of that name, created with this role and *no password* if missing: it cannot
    log in, and acts only through the tokens :func:`issue_token` gives it (a scenario run's
    operator, which owns the service's database, holds one without a password to type or
    hash). An admin's password reset gives it one."""
    existing = db.scalar(select(User).where(User.username == username))
    if existing is not None:
        return existing
    _check_username(username)
    return _add_user(db, username, NO_PASSWORD, role)


def authenticate(db: Session, username: str, password: str) -> User:
    user = db.scalar(select(User).where(User.username == username))
    if user is None or user.password_hash == NO_PASSWORD:
        verify_password(password, _DUMMY_HASH)  # same cost whether or not the user exists
        raise AuthenticationError("wrong username or password")
    if not verify_password(password, user.password_hash):
        raise AuthenticationError("wrong username or password")
    if user.disabled:  # said only to who knows the password
        raise AuthenticationError(f"user {username!r} is disabled")
    if needs_rehash(user.password_hash):  # made at an older cost: upgraded in place
        user.password_hash = hash_password(password)
    return user


def issue_token(db: Session, user: User, ttl_s: float) -> str:
    token = new_token()
    issued = _now()
    db.add(
        ApiToken(
            token_hash=token_digest(token),
            user_id=user.id,
            issued_at=issued,
            expires_at=issued + timedelta(seconds=ttl_s),
            revoked=False,
        )
    )
    db.flush()
    return token


def resolve_token(db: Session, token: str) -> User:
    """The user of a valid ``token``, in one query (every request asks it);
    :class:`InvalidTokenError` when the token is unknown, revoked, expired or its user's is
    gone or disabled."""
    found = db.execute(
        select(ApiToken.revoked, ApiToken.expires_at, User)
        .outerjoin(User, User.id == ApiToken.user_id)
        .where(ApiToken.token_hash == token_digest(token))
    ).first()
    if found is None or found[0]:
        raise InvalidTokenError("unknown or revoked token")
    _revoked, expires_at, user = found
    expires = expires_at if expires_at.tzinfo else expires_at.replace(tzinfo=UTC)
    if expires <= _now():
        raise InvalidTokenError("token expired")
    if user is None:
        raise InvalidTokenError("token of a deleted user")
    if user.disabled:
        raise InvalidTokenError("token of a disabled user")
    return user


def revoke_token(db: Session, token: str) -> None:
    row = db.scalar(select(ApiToken).where(ApiToken.token_hash == token_digest(token)))
    if row is not None:
        row.revoked = True
        db.flush()


def require_role(user: User, role: Role) -> None:
    if Role(user.role).rank < role.rank:
        raise PermissionDeniedError(f"{role.value} role needed, {user.username} is {user.role}")


def revoke_tokens_of(db: Session, user: User) -> int:
    """Revoke every token of ``user`` still valid; how many were."""
    result = db.execute(
        update(ApiToken)
        .where(ApiToken.user_id == user.id, ApiToken.revoked.is_(False))
        .values(revoked=True)
    )
    db.flush()
    return int(getattr(result, "rowcount", 0) or 0)


def get_user(db: Session, username: str) -> User:
    """The user of that name; :class:`NotFoundError` if there is none."""
    user = db.scalar(select(User).where(User.username == username))
    if user is None:
        raise NotFoundError(f"no user {username!r}")
    return user


def set_disabled(db: Session, admin: User, username: str, *, disabled: bool) -> User:
    """Disable (their tokens revoked) or enable a user. An admin cannot disable themself: the
    last admin would lock everyone out."""
    user = get_user(db, username)
    if disabled and user.id == admin.id:
        raise ConflictError("an admin cannot disable their own account")
    user.disabled = disabled
    if disabled:
        revoke_tokens_of(db, user)
    db.flush()
    return user


def reset_password(db: Session, username: str, password: str) -> User:
    """Set a new password for the user and revoke their tokens."""
    _check_password(password)
    user = get_user(db, username)
    user.password_hash = hash_password(password)
    revoke_tokens_of(db, user)
    return user
