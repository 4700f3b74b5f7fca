"""Where a scenario's line comes from: the one line resolver of runs, generators and spaces.

A scenario names its line in one of two ways (docs/scenarios.md, "The line"):

- ``line = "ID"``: a stored line. The shipped (built-in) lines come first, so that a library
  scenario runs on the same line whatever database lies about; any other id is read, at its
  current version, from the database a trackside would use: the run's ``database_url``
  (``ATO_DATABASE_URL``, else the trackside's default ``sqlite:///ato.db``).
- ``line_file = "PATH"`` (relative to the scenario file): a line document in our format
  (JSON, ``trackdb/line.schema.json``) or, with a ``[line_import]`` table, a RailJSON
  infrastructure from which a line is built between two operational points, with the options of
  ``ato trackdb import --format railjson``.

Every failure is a :class:`ScenarioLineError` that names the file or the id and the reason (the
run cannot be made: ``ato run`` exits 2); nothing is written anywhere while resolving.
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import make_url
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session

from deploy.scenario.run_context import ScenarioRunError
from deploy.scenario.schema import LineImportSpec, ScenarioSpec
from trackdb import (
    SEED_LINES,
    Line,
    LineNotFoundError,
    LineValidationError,
    RailJsonError,
    load_seed_line,
)

__all__ = [
    "MAX_LINE_FILE_BYTES",
    "ScenarioLineError",
    "line_from_file",
    "resolve_line",
    "stored_line",
]

MAX_LINE_FILE_BYTES = 64 * 1024 * 1024
"""The largest line file a scenario may name [bytes] (a RailJSON document of 50 MB fits)."""


class ScenarioLineError(ScenarioRunError):
    """The scenario's line cannot be had: which file or id, and why."""


def resolve_line(spec: ScenarioSpec, *, database_url: str | None = None) -> Line:
    """The line ``spec`` runs on.

    Parameters
    ----------
    spec
        The scenario; a relative ``line_file`` is taken from the working directory (the loader
        has already made it relative to the scenario file).
    database_url
        Where a line id that is not built in is looked up; None: built-in lines only.

    Raises
    ------
    ScenarioLineError
        No such line, or the file cannot be read or is not a valid line.
    """
    if spec.line_file is not None:
        return line_from_file(Path(spec.line_file), spec.line_import)
    assert spec.line is not None  # the schema asks for one of line and line_file
    return stored_line(spec.line, database_url=database_url)


def stored_line(line_id: str, *, database_url: str | None = None) -> Line:
    """A built-in line, else the current version of ``line_id`` in the database.

    Raises
    ------
    ScenarioLineError
        Neither has it (or the database cannot be read).
    """
    if line_id in SEED_LINES:
        return load_seed_line(line_id)
    built_in = ", ".join(SEED_LINES)
    if database_url is None:
        raise ScenarioLineError(f"line {line_id!r}: not a built-in line ({built_in})")
    where = _database_name(database_url)
    url = make_url(database_url)
    # Reading must not leave an empty database file behind a misspelt URL.
    file_database = url.drivername.startswith("sqlite") and url.database not in (
        None,
        "",
        ":memory:",
    )
    if file_database and not Path(str(url.database)).is_file():
        raise ScenarioLineError(
            f"line {line_id!r}: not a built-in line ({built_in}), and no database at {where}"
        )
    from trackdb import storage
    from trackside.db import create_database_engine

    engine = create_database_engine(database_url)
    try:
        with Session(engine) as session:
            return storage.get_line(session, line_id)
    except LineNotFoundError as exc:
        raise ScenarioLineError(
            f"line {line_id!r}: not a built-in line ({built_in}), nor stored in {where}"
        ) from exc
    except (SQLAlchemyError, LineValidationError) as exc:
        raise ScenarioLineError(f"line {line_id!r}: cannot read it from {where}: {exc}") from exc
    finally:
        engine.dispose()


def _database_name(database_url: str) -> str:
    """The URL without its password, for messages."""
    try:
        return make_url(database_url).render_as_string(hide_password=True)
    except Exception:  # a message's detail; the URL itself is refused where it is used
        return "<unparsable database URL>"


def line_from_file(path: Path, line_import: LineImportSpec | None = None) -> Line:
    """The line in ``path``: our line document, or with ``line_import`` a RailJSON import.

    Raises
    ------
    ScenarioLineError
        The file cannot be read, is too large, or holds no valid line.
    """
    try:
        size = path.stat().st_size
        if size > MAX_LINE_FILE_BYTES:
            raise ScenarioLineError(
                f"line_file {path}: {size} bytes, more than the {MAX_LINE_FILE_BYTES} allowed"
            )
        document = path.read_bytes()
    except OSError as exc:
        raise ScenarioLineError(f"line_file {path}: cannot read it: {exc.strerror}") from exc
    if line_import is None:
        from trackdb import parse_line

        try:
            return parse_line(document)
        except LineValidationError as exc:
            problems = "; ".join(exc.problems[:5])
            more = f" (and {len(exc.problems) - 5} more)" if len(exc.problems) > 5 else ""
            reason = f"not a valid line: {problems}{more}"
            raise ScenarioLineError(f"line_file {path}: {reason}") from exc
    return _railjson_line(path, document, line_import)


def _railjson_line(path: Path, document: bytes, options: LineImportSpec) -> Line:
    """A line built from a RailJSON infrastructure, as ``ato trackdb import`` builds it."""
    from trackdb.railjson import line_from_railjson

    try:
        return line_from_railjson(
            document,
            from_op=options.from_op,
            to_op=options.to_op,
            via=options.via,
            line_id=options.id,
            name=options.name,
            default_speed_kmh=options.default_speed_kmh,
            speed_tag=options.speed_tag,
        )
    except RailJsonError as exc:
        raise ScenarioLineError(f"line_file {path}: RailJSON: {exc}") from exc
    except LineValidationError as exc:
        reason = "; ".join(exc.problems[:5])
        raise ScenarioLineError(f"line_file {path}: RailJSON: not a valid line: {reason}") from exc
