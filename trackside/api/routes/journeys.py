"""Journeys: plan, validate, store with versions."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query, status
from pydantic import BaseModel

from trackdb.journey import Journey, JourneyCheck
from trackside.api.deps import DriverUser, ObserverUser, SessionDep
from trackside.errors import ConflictError, NotFoundError
from trackside.services import journeys as service

router = APIRouter(prefix="/journeys", tags=["journeys"])


class LegPublic(BaseModel):
    index: int
    from_id: str
    to_id: str
    distance_m: float
    scheduled_s: float
    minimum_s: float
    shortfall_s: float


class JourneyCheckPublic(BaseModel):
    valid: bool
    problems: list[str]
    legs: list[LegPublic]
    line_version: str

    @classmethod
    def from_check(cls, check: JourneyCheck, line_version: str) -> JourneyCheckPublic:
        legs = [
            LegPublic(
                index=leg.index,
                from_id=leg.from_id,
                to_id=leg.to_id,
                distance_m=leg.distance_m,
                scheduled_s=leg.scheduled_s,
                minimum_s=leg.minimum_s,
                shortfall_s=leg.shortfall_s,
            )
            for leg in check.legs
        ]
        return cls(
            valid=check.valid, problems=list(check.problems), legs=legs, line_version=line_version
        )


class JourneyPublic(BaseModel):
    journey: Journey
    version: int
    line_version: str
    created_by: str

    @classmethod
    def from_stored(cls, stored: service.StoredJourney) -> JourneyPublic:
        return cls(
            journey=stored.journey,
            version=stored.version,
            line_version=stored.line_version,
            created_by=stored.created_by,
        )


def _not_found(exc: NotFoundError) -> HTTPException:
    return HTTPException(status_code=status.HTTP_404_NOT_FOUND, detail=str(exc))


@router.post("/validate")
def validate_journey(journey: Journey, db: SessionDep, _user: ObserverUser) -> JourneyCheckPublic:
    """Check a journey against the current version of its line, without storing it."""
    try:
        check, line_version = service.validate_journey(db, journey)
    except NotFoundError as exc:
        raise _not_found(exc) from exc
    return JourneyCheckPublic.from_check(check, line_version)


@router.post("", status_code=status.HTTP_201_CREATED)
def create_journey(journey: Journey, db: SessionDep, user: DriverUser) -> JourneyPublic:
    """Store a journey as its next version; an invalid journey is refused with its problems."""
    try:
        stored = service.create_journey(db, journey, created_by=user.username)
    except NotFoundError as exc:
        raise _not_found(exc) from exc
    except service.InvalidJourneyError as exc:
        check = JourneyCheckPublic.from_check(exc.check, exc.line_version)
        detail: dict[str, Any] = {"message": "journey not valid on its line"} | check.model_dump()
        raise HTTPException(status_code=422, detail=detail) from exc
    except ConflictError as exc:
        raise HTTPException(status_code=status.HTTP_409_CONFLICT, detail=str(exc)) from exc
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
    try:
        return JourneyPublic.from_stored(service.get_journey(db, journey_id, version))
    except NotFoundError as exc:
        raise _not_found(exc) from exc
