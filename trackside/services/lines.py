"""Lines: the track database as the trackside serves it (listing, import, export, profiles).

Storage is :mod:`trackdb.storage`; this module adds the trackside's policies: which seed lines are
imported at start-up, whether an import stored a new version, and how a line is sampled for
plotting.
Errors are trackdb's (``LineValidationError``, ``LineNotFoundError``, ``LineConflictError``) and
:class:`~trackside.errors.InvalidRequestError` for a profile range the service refuses.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from sqlalchemy.orm import Session

from trackdb import SEED_LINES, Line, LineNotFoundError, TrackMap, parse_line, storage
from trackdb.storage import LineSummary
from trackside.errors import InvalidRequestError

__all__ = [
    "DEFAULT_PROFILE_POINTS",
    "MAX_PROFILE_POINTS",
    "LineImport",
    "LineProfile",
    "current_version",
    "ensure_seed_lines",
    "import_line",
    "line_document",
    "line_profile",
    "line_versions",
    "list_lines",
    "profile_chainages",
]

MAX_PROFILE_POINTS = 20_001
"""Most samples one profile request may ask for."""
DEFAULT_PROFILE_POINTS = 1_001
"""Samples over the range when no step is given."""

list_lines = storage.list_lines
line_versions = storage.line_versions
current_version = storage.current_version


@dataclass(frozen=True, slots=True)
class LineImport:
    """The outcome of an import: the stored version, and whether it was new to the database."""

    summary: LineSummary
    new_version: bool


@dataclass(frozen=True, slots=True)
class LineProfile:
    """A line sampled at chainages, SI units; ``altitude_m`` is None without a geodetic polyline.

    ``chainage_m`` holds the requested chainages, not wrapped, so that a plot over a ring's origin
    stays continuous; the values are those at the wrapped chainage.
    """

    line_id: str
    version: str
    ring: bool
    length_m: float
    chainage_m: list[float]
    gradient_permille: list[float]
    curvature_per_m: list[float]
    speed_limit_mps: list[float]
    mrsp_mps: list[float]
    altitude_m: list[float] | None


def import_line(db: Session, body: bytes | Mapping[str, Any]) -> LineImport:
    """Validate and store a line document (raw JSON or decoded); it becomes the current version.

    Raises
    ------
    LineValidationError
        The document is not JSON or breaks the schema; nothing was written.
    LineConflictError
        A concurrent import of the same line won the race.
    """
    line = parse_line(body)
    version = line.version()
    try:
        known = {summary.version for summary in storage.line_versions(db, line.id)}
    except LineNotFoundError:
        known = set()
    storage.import_line(db, line)
    summary = next(s for s in storage.line_versions(db, line.id) if s.version == version)
    return LineImport(summary=summary, new_version=version not in known)


def line_document(db: Session, line_id: str, version: str | None = None) -> tuple[str, str]:
    """The canonical JSON of the line (current or given version) and its version."""
    if version is None:
        version = storage.current_version(db, line_id)
    return storage.export_line(db, line_id, version), version


def ensure_seed_lines(
    db: Session, seed_lines: Mapping[str, Callable[[], Line]] = SEED_LINES
) -> list[str]:
    """Import each seed line whose id is not stored; a stored id, of any version, is kept.

    Returns the ids imported.
    """
    imported = []
    for line_id, build in seed_lines.items():
        try:
            storage.current_version(db, line_id)
        except LineNotFoundError:
            storage.import_line(db, build())
            imported.append(line_id)
    return imported


def line_profile(
    db: Session,
    line_id: str,
    *,
    from_m: float | None = None,
    to_m: float | None = None,
    step_m: float | None = None,
    version: str | None = None,
) -> LineProfile:
    """The line's profiles sampled over ``[from_m, to_m]`` every ``step_m`` [m], for plotting.

    Defaults: the whole line in :data:`DEFAULT_PROFILE_POINTS` samples. See
    :func:`profile_chainages` for the range's rules.

    Raises
    ------
    LineNotFoundError
        No such line or version.
    InvalidRequestError
        The range or step is refused.
    """
    line = storage.get_line(db, line_id, version)
    chainages = profile_chainages(line, from_m=from_m, to_m=to_m, step_m=step_m)
    track = TrackMap(line)
    altitudes = [track.altitude_m(c) for c in chainages] if line.geodetic else None
    return LineProfile(
        line_id=line.id,
        version=track.version,
        ring=line.ring,
        length_m=line.length_m,
        chainage_m=chainages,
        gradient_permille=[track.gradient_permille(c) for c in chainages],
        curvature_per_m=[track.curvature_per_m(c) for c in chainages],
        speed_limit_mps=[track.speed_limit_mps(c) for c in chainages],
        mrsp_mps=[track.mrsp_mps(c) for c in chainages],
        altitude_m=altitudes,
    )


def profile_chainages(
    line: Line, *, from_m: float | None, to_m: float | None, step_m: float | None
) -> list[float]:
    """Sample chainages [m]: ``from_m``, then every ``step_m``, and ``to_m`` last.

    ``0 <= from_m < to_m``; on an open line ``to_m <= length_m``, on a ring ``to_m`` may pass
    the length (the profile wraps). At most :data:`MAX_PROFILE_POINTS` samples.

    Raises
    ------
    InvalidRequestError
        A bound or step out of range, or too many samples.
    """
    start = 0.0 if from_m is None else from_m
    end = line.length_m if to_m is None else to_m
    if not (math.isfinite(start) and math.isfinite(end)) or start < 0.0:
        raise InvalidRequestError(f"from {start} m, to {end} m: finite, from at least 0 m")
    if end <= start:
        raise InvalidRequestError(f"to ({end} m) must be after from ({start} m)")
    if not line.ring and end > line.length_m:
        raise InvalidRequestError(f"to ({end} m) beyond the end of line {line.id!r}")
    step = (end - start) / (DEFAULT_PROFILE_POINTS - 1) if step_m is None else step_m
    if not math.isfinite(step) or step <= 0.0:
        raise InvalidRequestError(f"step ({step} m) must be positive")
    ratio = (end - start) / step
    steps = math.floor(ratio * (1.0 + 1e-12)) if ratio < MAX_PROFILE_POINTS else MAX_PROFILE_POINTS
    on_grid = end - (start + steps * step) <= 1e-9 * max(1.0, end)
    if (steps + 1 if on_grid else steps + 2) > MAX_PROFILE_POINTS:
        raise InvalidRequestError(
            f"step {step} m over {end - start} m: more than {MAX_PROFILE_POINTS} samples"
        )
    chainages = [start + index * step for index in range(steps + 1)]
    if on_grid:
        chainages[-1] = end
    else:
        chainages.append(end)
    return chainages
