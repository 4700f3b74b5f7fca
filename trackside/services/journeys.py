"""Journeys: validated against the current version of their line, stored with versions."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime

from sqlalchemy import delete, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from trackdb import TrackMap
from trackdb.journey import Journey, JourneyCheck, check_journey
from trackdb.storage import LineNotFoundError, get_line
from trackside.errors import ConflictError, InvalidJourneyError, NotFoundError
from trackside.models import JourneyRow

__all__ = [
    "StoredJourney",
    "create_journey",
    "delete_journey_version",
    "get_journey",
    "line_top_speed_mps",
    "list_journeys",
    "validate_journey",
]


@dataclass(frozen=True)
class StoredJourney:
    journey: Journey
    version: int
    line_version: str
    created_by: str
    created_at: datetime


def validate_journey(db: Session, journey: Journey) -> tuple[JourneyCheck, str]:
    """Check a journey against the current version of its line: (check, line version)."""
    try:
        line = get_line(db, journey.line_id)
    except LineNotFoundError as exc:
        raise NotFoundError(f"no line {journey.line_id!r}") from exc
    track_map = TrackMap(line)
    return check_journey(journey, track_map), track_map.version


def create_journey(db: Session, journey: Journey, *, created_by: str) -> StoredJourney:
    """Store a valid journey as the next version of its id; an invalid one is refused whole."""
    check, line_version = validate_journey(db, journey)
    if not check.valid:
        raise InvalidJourneyError(check, line_version)
    latest = db.scalar(
        select(func.max(JourneyRow.version)).where(JourneyRow.journey_id == journey.id)
    )
    row = JourneyRow(
        journey_id=journey.id,
        version=(latest or 0) + 1,
        line_id=journey.line_id,
        line_version=line_version,
        document=journey.model_dump_json(),
        created_by=created_by,
        created_at=datetime.now(UTC),
    )
    db.add(row)
    try:
        db.flush()
    except IntegrityError as exc:
        raise ConflictError(f"journey {journey.id} changed meanwhile; try again") from exc
    return _stored(row)


def delete_journey_version(db: Session, journey_id: str, version: int) -> None:
    """Remove one version of a journey (the planner's, which the vehicle did not take)."""
    db.execute(
        delete(JourneyRow).where(JourneyRow.journey_id == journey_id, JourneyRow.version == version)
    )


def line_top_speed_mps(db: Session, line_id: str) -> float:
    """The highest speed limit of the current version of a line [m/s]."""
    try:
        track_map = TrackMap(get_line(db, line_id))
    except LineNotFoundError as exc:
        raise NotFoundError(f"no line {line_id!r}") from exc
    sections = track_map.mrsp_window(0.0, track_map.length_m)
    return max(section.speed_mps for section in sections)


def get_journey(db: Session, journey_id: str, version: int | None = None) -> StoredJourney:
    query = select(JourneyRow).where(JourneyRow.journey_id == journey_id)
    if version is not None:
        query = query.where(JourneyRow.version == version)
    row = db.scalar(query.order_by(JourneyRow.version.desc()).limit(1))
    if row is None:
        raise NotFoundError(f"no journey {journey_id!r}" + (f" v{version}" if version else ""))
    return _stored(row)


def list_journeys(db: Session) -> list[StoredJourney]:
    """The latest version of every journey."""
    latest = (
        select(JourneyRow.journey_id, func.max(JourneyRow.version).label("version"))
        .group_by(JourneyRow.journey_id)
        .subquery()
    )
    rows = db.scalars(
        select(JourneyRow)
        .join(
            latest,
            (JourneyRow.journey_id == latest.c.journey_id)
            & (JourneyRow.version == latest.c.version),
        )
        .order_by(JourneyRow.journey_id)
    )
    return [_stored(row) for row in rows]


def _stored(row: JourneyRow) -> StoredJourney:
    return StoredJourney(
        journey=Journey.model_validate_json(row.document),
        version=row.version,
        line_version=row.line_version,
        created_by=row.created_by,
        created_at=row.created_at,
    )
