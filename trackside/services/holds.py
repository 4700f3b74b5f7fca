"""Vehicle holds: one driver at a time holds a vehicle, and only the holder commands it.

A hold is a lease (``Settings.hold_lease_s``, 60 s by default). The holder renews it by
selecting the vehicle again, by each command they send, and while one of their consoles is
connected (the WebSocket streams renew every hold of their user); a console closed or crashed
stops renewing, and once the lease has run out the vehicle is free for any driver. An expired
hold's row stays until someone selects the vehicle: every read here treats it as no hold.
"""

from __future__ import annotations

import threading
from datetime import UTC, datetime, timedelta

from sqlalchemy import select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from trackside.errors import ConflictError
from trackside.models import Role, User, VehicleHold

__all__ = [
    "DEFAULT_LEASE_S",
    "changes",
    "check_holder",
    "expires_at",
    "holder",
    "holders",
    "release",
    "renew_all",
    "select_vehicle",
]

DEFAULT_LEASE_S = 60.0
"""A hold's lease when the settings say nothing else [s]."""


_changed = 0
_changed_lock = threading.Lock()


def _now() -> datetime:
    return datetime.now(UTC)


def changes() -> int:
    """How many times a hold was taken, taken over or given up in this process: a cache of the
    holders is stale once it moves (renewals only extend a lease, and do not count)."""
    return _changed


def _count_change() -> None:
    global _changed
    with _changed_lock:
        _changed += 1


def expires_at(hold: VehicleHold) -> datetime:
    """The end of the hold's lease, in UTC (SQLite gives back naive datetimes)."""
    at = hold.expires_at
    return at if at.tzinfo is not None else at.replace(tzinfo=UTC)


def _live(hold: VehicleHold | None, now: datetime) -> VehicleHold | None:
    return hold if hold is not None and expires_at(hold) > now else None


def holders(db: Session) -> dict[str, tuple[str, datetime]]:
    """Every hold in force, by vehicle: its holder and the end of its lease in UTC (expired
    ones left out). Columns, not ORM objects: the fleet's list and stream read it often, and
    with a thousand held vehicles building the objects took most of a request."""
    now = _now()
    held = {}
    columns = select(VehicleHold.vehicle_id, VehicleHold.username, VehicleHold.expires_at)
    for vehicle_id, username, at in db.execute(columns):
        until = at if at.tzinfo is not None else at.replace(tzinfo=UTC)
        if until > now:
            held[vehicle_id] = (username, until)
    return held


def holder(db: Session, vehicle_id: str) -> VehicleHold | None:
    """The vehicle's hold, if anyone holds it and the lease runs."""
    return _live(db.get(VehicleHold, vehicle_id), _now())


def select_vehicle(db: Session, vehicle_id: str, user: User, *, lease_s: float) -> VehicleHold:
    """Take the vehicle for ``user`` for ``lease_s`` [s]; the holder selecting again renews the
    lease (idempotent). Raises :class:`ConflictError` naming the holder when someone else
    holds it."""
    now = _now()
    until = now + timedelta(seconds=lease_s)
    hold = db.get(VehicleHold, vehicle_id)
    if hold is None:
        return _create(db, vehicle_id, user, now, until)
    if _live(hold, now) is None:
        return _take_over(db, hold, user, now, until)
    if hold.username != user.username:
        raise ConflictError(f"{vehicle_id} is held by {hold.username}")
    hold.expires_at = until
    db.flush()
    return hold


def _create(
    db: Session, vehicle_id: str, user: User, now: datetime, until: datetime
) -> VehicleHold:
    hold = VehicleHold(vehicle_id=vehicle_id, username=user.username, since=now, expires_at=until)
    db.add(hold)
    try:
        db.flush()
    except IntegrityError as exc:  # another driver took it meanwhile
        db.rollback()
        raise ConflictError(f"{vehicle_id} was just taken by another user") from exc
    _count_change()
    return hold


def _take_over(
    db: Session, hold: VehicleHold, user: User, now: datetime, until: datetime
) -> VehicleHold:
    """Give an expired hold to ``user``: only if the row is still the expired one read (a
    compare-and-set, so that of two drivers taking it at once, or the holder renewing at the
    last moment, one wins and the other is told)."""
    taken = db.execute(
        update(VehicleHold)
        .where(
            VehicleHold.vehicle_id == hold.vehicle_id,
            VehicleHold.username == hold.username,
            VehicleHold.expires_at == hold.expires_at,
        )
        .values(username=user.username, since=now, expires_at=until)
        .execution_options(synchronize_session=False)
    )
    if getattr(taken, "rowcount", 0) != 1:
        raise ConflictError(f"{hold.vehicle_id} was just taken by another user")
    db.refresh(hold)
    _count_change()
    return hold


def renew_all(db: Session, username: str, *, lease_s: float) -> int:
    """Extend every hold of ``username`` still in force to ``lease_s`` [s] from now (their
    console is connected); how many. An expired hold is not brought back."""
    now = _now()
    renewed = db.execute(
        update(VehicleHold)
        .where(VehicleHold.username == username, VehicleHold.expires_at > now)
        .values(expires_at=now + timedelta(seconds=lease_s))
        .execution_options(synchronize_session=False)
    )
    return int(getattr(renewed, "rowcount", 0) or 0)


def release(db: Session, vehicle_id: str, user: User) -> None:
    """Give the vehicle up; an admin may release anyone's hold. Releasing a vehicle nobody
    holds (or whose hold has expired) does nothing."""
    hold = holder(db, vehicle_id)
    if hold is None:
        return
    if hold.username != user.username and Role(user.role) is not Role.ADMIN:
        raise ConflictError(f"{vehicle_id} is held by {hold.username}")
    db.delete(hold)
    db.flush()
    _count_change()


def check_holder(db: Session, vehicle_id: str, user: User, *, lease_s: float | None = None) -> None:
    """Raise :class:`ConflictError` unless ``user`` holds the vehicle; with ``lease_s`` [s],
    renew the hold's lease (a command is the holder's sign of life)."""
    now = _now()
    stored = db.get(VehicleHold, vehicle_id)
    hold = _live(stored, now)
    if hold is None:
        if stored is not None and stored.username == user.username:
            raise ConflictError(f"your hold on {vehicle_id} has expired: select it again")
        raise ConflictError(f"select {vehicle_id} first")
    if hold.username != user.username:
        raise ConflictError(f"{vehicle_id} is held by {hold.username}")
    if lease_s is not None:
        hold.expires_at = now + timedelta(seconds=lease_s)
        db.flush()
