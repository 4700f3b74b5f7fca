"""Journeys: plan, validate, store with versions (audited)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, status

from trackdb.journey import Journey
from trackside.api.deps import AuditDep, DriverUser, ObserverUser, SessionDep
from trackside.api.schemas import JourneyCheckPublic, JourneyPublic
from trackside.services import journeys as service

__all__ = ["router"]

router = APIRouter(prefix="/journeys", tags=["journeys"])


@router.post("/validate")
def validate_journey(journey: Journey, db: SessionDep, _user: ObserverUser) -> JourneyCheckPublic:
    """Check a journey against the current version of its line, without storing it."""
    check, line_version = service.validate_journey(db, journey)
    return JourneyCheckPublic.from_check(check, line_version)


@router.post("", status_code=status.HTTP_201_CREATED)
def create_journey(
    journey: Journey, db: SessionDep, user: DriverUser, trail: AuditDep
) -> JourneyPublic:
    """Store a journey as its next version; an invalid journey is refused with its problems."""
    request = {"journey_id": journey.id, "line_id": journey.line_id}
    with trail.action(user.username, "journey.create", request=request) as note:
        stored = service.create_journey(db, journey, created_by=user.username)
        note.request["version"] = stored.version
    return JourneyPublic.from_stored(stored)


@router.get("")
def list_journeys(db: SessionDep, _user: ObserverUser) -> list[JourneyPublic]:
    """The latest version of every stored journey."""
    return [JourneyPublic.from_stored(stored) for stored in service.list_journeys(db)]


@router.get("/{journey_id}")
def read_journey(
    journey_id: str,
    db: SessionDep,
    _user: ObserverUser,
    version: Annotated[int | None, Query(ge=1, le=2**31 - 1)] = None,
) -> JourneyPublic:
    """One journey, its latest version unless a version is asked for."""
    return JourneyPublic.from_stored(service.get_journey(db, journey_id, version))
