"""The errors trackdb raises, in one place, re-exported by ``trackdb``.

::

    TrackDataError (Exception)                  base of trackdb's errors
    ├── LineValidationError (ValueError)        a line document breaks the schema's rules;
    │                                           ``problems`` lists every one with its location
    ├── LineNotFoundError (LookupError)         no stored line of that id, or not that version
    ├── NoGeodeticPolylineError (LookupError)   a geodetic query on a line without a polyline
    ├── RailJsonError (ValueError)              a RailJSON document that cannot become a line;
    │                                           ``json_path`` names the place, ``reason`` why
    └── LineConflictError                       the database refused a write that raced with
                                                another import of the same line (roll back, retry)

Errors of the database driver are translated at the storage boundary (``raise ... from exc``);
callers of :mod:`trackdb.storage` never need to catch SQLAlchemy's.
"""

from __future__ import annotations

__all__ = [
    "LineConflictError",
    "LineNotFoundError",
    "LineValidationError",
    "NoGeodeticPolylineError",
    "RailJsonError",
    "TrackDataError",
]


class TrackDataError(Exception):
    """Base of trackdb's errors."""


class LineValidationError(TrackDataError, ValueError):
    """A line that breaks the schema's rules; ``problems`` lists each one with its location."""

    def __init__(self, line_id: str, problems: list[str]) -> None:
        super().__init__(f"line {line_id!r}: " + "; ".join(problems))
        self.line_id = line_id
        self.problems = problems


class LineNotFoundError(TrackDataError, LookupError):
    """No stored line of that id, or the line has no such version."""

    def __init__(self, line_id: str, version: str | None = None) -> None:
        if version is None:
            message = f"no line {line_id!r}"
        else:
            message = f"line {line_id!r} has no version {version!r}"
        super().__init__(message)
        self.line_id = line_id
        self.version = version


class LineConflictError(TrackDataError):
    """A write raced with another import of the same line; roll the session back and retry."""


class NoGeodeticPolylineError(TrackDataError, LookupError):
    """A geodetic query on a line that has no geodetic polyline."""


class RailJsonError(TrackDataError, ValueError):
    """A RailJSON document that cannot become a line: ``json_path`` names the place in the
    document (``$.track_sections[12].length``), ``reason`` says what is wrong there."""

    def __init__(self, json_path: str, reason: str) -> None:
        super().__init__(f"{json_path}: {reason}")
        self.json_path = json_path
        self.reason = reason
