"""Vehicle holds: one driver at a time holds a vehicle, and only the holder commands it."""

from __future__ import annotations

from datetime import UTC, datetime

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from trackside.errors import ConflictError
from trackside.models import Role, User, VehicleHold

__all__ = ["check_holder", "holder", "holders", "release", "select_vehicle"]


def holders(db: Session) -> dict[str, VehicleHold]:
    """Every hold, by vehicle."""
    return {hold.vehicle_id: hold for hold in db.scalars(select(VehicleHold))}


def holder(db: Session, vehicle_id: str) -> VehicleHold | None:
    """The vehicle's hold, if anyone holds it."""
    return db.get(VehicleHold, vehicle_id)


def select_vehicle(db: Session, vehicle_id: str, user: User) -> VehicleHold:
    """Take the vehicle for ``user``; the holder selecting again keeps the hold (idempotent).
    Raises :class:`ConflictError` naming the holder when someone else holds it."""
    hold = db.get(VehicleHold, vehicle_id)
    if hold is not None:
        if hold.username != user.username:
            raise ConflictError(f"{vehicle_id} is held by {hold.username}")
        return hold
    hold = VehicleHold(vehicle_id=vehicle_id, username=user.username, since=datetime.now(UTC))
    db.add(hold)
    try:
        db.flush()
    except IntegrityError as exc:  # another driver took it meanwhile
        db.rollback()
        raise ConflictError(f"{vehicle_id} was just taken by another user") from exc
    return hold


def release(db: Session, vehicle_id: str, user: User) -> None:
    """Give the vehicle up; an admin may release anyone's hold. Releasing a vehicle nobody
    holds does nothing."""
    hold = db.get(VehicleHold, vehicle_id)
    if hold is None:
        return
    if hold.username != user.username and Role(user.role) is not Role.ADMIN:
        raise ConflictError(f"{vehicle_id} is held by {hold.username}")
    db.delete(hold)
    db.flush()


def check_holder(db: Session, vehicle_id: str, user: User) -> None:
    """Raise :class:`ConflictError` unless ``user`` holds the vehicle."""
    hold = db.get(VehicleHold, vehicle_id)
    if hold is None:
        raise ConflictError(f"select {vehicle_id} first")
    if hold.username != user.username:
        raise ConflictError(f"{vehicle_id} is held by {hold.username}")
