"""Lines in a database: every imported version kept, one current version per line id.

Two tables, on trackdb's own :class:`TrackDataBase` (the trackside's Alembic migrations create
them, revision ``0002``; tests may use ``metadata.create_all``):

- ``line_versions``: one row per (line id, version), with the canonical JSON document whose
  SHA-256 is the version (:meth:`trackdb.schema.Line.version`), and the summary columns that
  listing needs without parsing documents;
- ``lines``: for each line id, the version currently in force.

The functions take a SQLAlchemy :class:`~sqlalchemy.orm.Session` and leave the transaction to
the caller, who commits. Importing validates the whole document before anything is written, so a
line that fails is rejected whole and the session is untouched. Importing makes the line's
version the current one; importing the current version again changes nothing.

Errors are those of :mod:`trackdb._exceptions`: ``LineValidationError``, ``LineNotFoundError``
and ``LineConflictError`` (SQLAlchemy's integrity errors translated).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    Boolean,
    DateTime,
    Float,
    ForeignKeyConstraint,
    Integer,
    MetaData,
    String,
    Text,
    UniqueConstraint,
    select,
)
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import DeclarativeBase, Mapped, Session, mapped_column

from trackdb._exceptions import LineConflictError, LineNotFoundError, LineValidationError
from trackdb.schema import Line, parse_line

__all__ = [
    "LineConflictError",
    "LineNotFoundError",
    "LineRow",
    "LineSummary",
    "LineValidationError",
    "LineVersionRow",
    "TrackDataBase",
    "current_version",
    "export_line",
    "get_line",
    "import_line",
    "line_versions",
    "list_lines",
    "metadata",
]

VERSION_LENGTH = 64  # hexadecimal SHA-256


class TrackDataBase(DeclarativeBase):
    """Declarative base of trackdb's tables, separate from the trackside's own models."""


metadata: MetaData = TrackDataBase.metadata


class LineVersionRow(TrackDataBase):
    """One imported version of a line: its canonical JSON and a summary."""

    __tablename__ = "line_versions"
    __table_args__ = (UniqueConstraint("line_id", "version", name="uq_line_versions_line_version"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    line_id: Mapped[str] = mapped_column(String(64), nullable=False)
    version: Mapped[str] = mapped_column(String(VERSION_LENGTH), nullable=False)
    schema_version: Mapped[int] = mapped_column(Integer, nullable=False)
    name: Mapped[str] = mapped_column(String(128), nullable=False)
    length_m: Mapped[float] = mapped_column(Float, nullable=False)
    ring: Mapped[bool] = mapped_column(Boolean, nullable=False)
    etcs_level: Mapped[int] = mapped_column(Integer, nullable=False)
    document: Mapped[str] = mapped_column(Text, nullable=False)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)


class LineRow(TrackDataBase):
    """A line id and the version of it currently in force."""

    __tablename__ = "lines"
    __table_args__ = (
        ForeignKeyConstraint(
            ["id", "version"],
            ["line_versions.line_id", "line_versions.version"],
            name="fk_lines_current_version",
        ),
    )

    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    version: Mapped[str] = mapped_column(String(VERSION_LENGTH), nullable=False)
    updated_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)


@dataclass(frozen=True, slots=True)
class LineSummary:
    """What a listing shows of one line version; ``created_at`` is when it was imported (UTC)."""

    id: str
    version: str
    name: str
    length_m: float
    ring: bool
    etcs_level: int
    created_at: datetime
    current: bool

    @classmethod
    def from_row(cls, row: LineVersionRow, *, current: bool) -> LineSummary:
        created = row.created_at
        if created.tzinfo is None:  # SQLite returns naive datetimes; they were stored in UTC
            created = created.replace(tzinfo=UTC)
        return cls(
            id=row.line_id,
            version=row.version,
            name=row.name,
            length_m=row.length_m,
            ring=row.ring,
            etcs_level=row.etcs_level,
            created_at=created,
            current=current,
        )


def import_line(session: Session, document: Line | Mapping[str, Any] | str | bytes) -> Line:
    """Validate a line and store it as the current version of its id.

    Parameters
    ----------
    session
        The caller's session; the caller commits.
    document
        A :class:`Line`, a decoded JSON object, or JSON text.

    Returns
    -------
    Line
        The line as stored; ``line.version()`` is its version.

    Raises
    ------
    LineValidationError
        The document breaks the schema; nothing was written.
    LineConflictError
        Another session stored the same version first; roll back and retry.
    """
    if isinstance(document, Line):
        document = document.model_dump(mode="json", round_trip=True)
    line = parse_line(document)
    version = line.version()
    try:
        if _version_row(session, line.id, version) is None:
            session.add(_new_version_row(line, version))
            session.flush()
        current = session.get(LineRow, line.id)
        if current is None:
            session.add(LineRow(id=line.id, version=version, updated_at=datetime.now(UTC)))
        elif current.version != version:
            current.version = version
            current.updated_at = datetime.now(UTC)
        session.flush()
    except IntegrityError as exc:
        raise LineConflictError(f"line {line.id!r}: concurrent import of {version}") from exc
    return line


def get_line(session: Session, line_id: str, version: str | None = None) -> Line:
    """The current line of that id, or the given version of it.

    Raises
    ------
    LineNotFoundError
        No line of that id is stored, or it has no such version.
    """
    return parse_line(export_line(session, line_id, version))


def export_line(session: Session, line_id: str, version: str | None = None) -> str:
    """The canonical JSON of the line (current or given version): its SHA-256 is the version.

    Raises
    ------
    LineNotFoundError
        No line of that id is stored, or it has no such version.
    """
    if version is None:
        version = current_version(session, line_id)
    row = _version_row(session, line_id, version)
    if row is None:
        raise LineNotFoundError(line_id, version)
    return row.document


def current_version(session: Session, line_id: str) -> str:
    """The version of the line currently in force; :class:`LineNotFoundError` if none."""
    current = session.get(LineRow, line_id)
    if current is None:
        raise LineNotFoundError(line_id)
    return current.version


def list_lines(session: Session) -> list[LineSummary]:
    """The current version of every stored line, by id."""
    rows = session.scalars(
        select(LineVersionRow)
        .join(
            LineRow,
            (LineRow.id == LineVersionRow.line_id) & (LineRow.version == LineVersionRow.version),
        )
        .order_by(LineVersionRow.line_id)
    )
    return [LineSummary.from_row(row, current=True) for row in rows]


def line_versions(session: Session, line_id: str) -> list[LineSummary]:
    """Every stored version of the line, oldest first; :class:`LineNotFoundError` if none."""
    current = current_version(session, line_id)
    rows = session.scalars(
        select(LineVersionRow).where(LineVersionRow.line_id == line_id).order_by(LineVersionRow.id)
    )
    return [LineSummary.from_row(row, current=row.version == current) for row in rows]


def _version_row(session: Session, line_id: str, version: str) -> LineVersionRow | None:
    return session.scalar(
        select(LineVersionRow).where(
            LineVersionRow.line_id == line_id, LineVersionRow.version == version
        )
    )


def _new_version_row(line: Line, version: str) -> LineVersionRow:
    return LineVersionRow(
        line_id=line.id,
        version=version,
        schema_version=line.schema_version,
        name=line.name,
        length_m=line.length_m,
        ring=line.ring,
        etcs_level=line.etcs_level,
        document=line.model_dump_json(round_trip=True),
        created_at=datetime.now(UTC),
    )
