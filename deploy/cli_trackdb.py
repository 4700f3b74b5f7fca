"""``ato trackdb ...``: track data in and out of the database (docs/trackdb.md).

- ``ato trackdb import FILE``: a line document of ours; ``--format railjson`` with ``--from``,
  ``--to``, ``[--via ...]`` and ``--id``: a line built from an OSRD RailJSON infrastructure.
  Bad input: exit 2, the problem on stderr, nothing stored.
- ``ato trackdb export LINE [--format geojson]``: the canonical JSON (or a GeoJSON
  FeatureCollection for map tools).
- ``ato trackdb list``, ``ato trackdb schema``, ``ato trackdb seed`` (the built-in lines).

Every command that opens the database first imports the built-in lines when it holds no line
at all, as the trackside does at start (``ATO_SEED_LINES=false`` turns both off); this happens
in the command's own transaction, so a refused import leaves the database as it was.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from trackdb import Line

__all__ = ["trackdb_app"]

trackdb_app = typer.Typer(help="Track data in and out of the database.", no_args_is_help=True)

DatabaseOption = Annotated[
    str | None,
    typer.Option(
        "--database", help="SQLAlchemy URL (default: ATO_DATABASE_URL, else sqlite:///ato.db)."
    ),
]


class ImportFormat(StrEnum):
    LINE = "line"
    RAILJSON = "railjson"


class ExportFormat(StrEnum):
    LINE = "line"
    GEOJSON = "geojson"


def _seed_on_empty() -> bool:
    import os

    from pydantic import TypeAdapter, ValidationError

    try:
        return TypeAdapter(bool).validate_python(os.environ.get("ATO_SEED_LINES", "true"))
    except ValidationError:
        return True


@contextmanager
def _session(database: str | None) -> Iterator[Session]:
    """The migrated database in one transaction, the built-in lines seeded if it has none."""
    from deploy.cli import _database_session
    from trackdb.storage import list_lines
    from trackside.services.lines import ensure_seed_lines

    with _database_session(database) as session:
        if _seed_on_empty() and not list_lines(session):
            ensure_seed_lines(session)
        yield session


FormatOption = Annotated[
    ImportFormat, typer.Option("--format", help="line (ours) or railjson (OSRD, 3.x).")
]
FromOption = Annotated[
    str | None, typer.Option("--from", help="RailJSON: the origin operational point.")
]
ToOption = Annotated[
    str | None, typer.Option("--to", help="RailJSON: the destination operational point.")
]
ViaOption = Annotated[
    list[str] | None,
    typer.Option("--via", help="RailJSON: an operational point to pass, in order (repeatable)."),
]
IdOption = Annotated[str | None, typer.Option("--id", help="RailJSON: the line's id.")]
NameOption = Annotated[
    str | None, typer.Option("--name", help="RailJSON: its name (ORIGIN – DESTINATION).")
]
SpeedOption = Annotated[
    float, typer.Option("--default-speed", help="RailJSON: km/h where no speed section applies.")
]
TagOption = Annotated[
    str | None,
    typer.Option("--speed-tag", help="RailJSON: use speed sections' limits for this tag."),
]


@trackdb_app.command("import")
def trackdb_import(
    file: Annotated[
        Path,
        typer.Argument(help="A line document, or a RailJSON infrastructure.", dir_okay=False),
    ],
    database: DatabaseOption = None,
    format: FormatOption = ImportFormat.LINE,
    from_op: FromOption = None,
    to_op: ToOption = None,
    via: ViaOption = None,
    line_id: IdOption = None,
    name: NameOption = None,
    default_speed: SpeedOption = 60.0,
    speed_tag: TagOption = None,
) -> None:
    """Validate and import a line; prints its id and version. Bad input: the problems, exit 2."""
    from trackdb import LineValidationError, RailJsonError
    from trackdb.storage import import_line

    try:
        if format is ImportFormat.RAILJSON:
            line: Line | bytes = _railjson_line(
                file, from_op, to_op, via or [], line_id, name, default_speed, speed_tag
            )
        else:
            line = _read(file)
        with _session(database) as session:
            stored = import_line(session, line)
    except RailJsonError as exc:
        typer.echo(f"{file}: {exc}", err=True)
        raise typer.Exit(code=2) from exc
    except LineValidationError as exc:
        typer.echo(
            f"{file}: line {exc.line_id!r} rejected, {len(exc.problems)} problem(s):", err=True
        )
        for problem in exc.problems:
            typer.echo(problem, err=True)
        raise typer.Exit(code=2) from exc
    typer.echo(f"{stored.id} {stored.version()}")
    if format is ImportFormat.RAILJSON:
        for stop in stored.stopping_points:
            typer.echo(
                f"stopping point {stop.id} at {stop.position_m:.1f} m: {stop.name}", err=True
            )


def _read(file: Path, limit: int | None = None) -> bytes:
    """The file's bytes; a missing file or one over ``limit`` bytes is bad input (exit 2)."""
    from trackdb import RailJsonError

    try:
        size = file.stat().st_size
        if limit is not None and size > limit:
            raise RailJsonError(
                "$",
                f"document of {size} bytes over the limit of {limit} bytes ({limit // 2**20} MiB)",
            )
        return file.read_bytes()
    except OSError as exc:
        typer.echo(f"{file}: {exc.strerror or exc}", err=True)
        raise typer.Exit(code=2) from exc


def _railjson_line(
    file: Path,
    from_op: str | None,
    to_op: str | None,
    via: list[str],
    line_id: str | None,
    name: str | None,
    default_speed_kmh: float,
    speed_tag: str | None,
) -> Line:
    from trackdb.railjson import MAX_DOCUMENT_BYTES, line_from_railjson

    if not (from_op and to_op and line_id):
        given = (("--from", from_op), ("--to", to_op), ("--id", line_id))
        missing = ", ".join(flag for flag, value in given if not value)
        typer.echo(f"--format railjson needs {missing}", err=True)
        raise typer.Exit(code=2)
    return line_from_railjson(
        _read(file, MAX_DOCUMENT_BYTES),
        from_op=from_op,
        to_op=to_op,
        via=via,
        line_id=line_id,
        name=name,
        default_speed_kmh=default_speed_kmh,
        speed_tag=speed_tag,
    )


@trackdb_app.command("export")
def trackdb_export(
    line: Annotated[str, typer.Argument(help="Line id.")],
    database: DatabaseOption = None,
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Write to this file, not stdout.")
    ] = None,
    version: Annotated[
        str | None, typer.Option("--version", help="A stored version; the current by default.")
    ] = None,
    format: Annotated[
        ExportFormat,
        typer.Option("--format", help="line (canonical JSON) or geojson (polyline and stops)."),
    ] = ExportFormat.LINE,
) -> None:
    """Print a line's canonical JSON (its SHA-256 is the line's version), or its GeoJSON."""
    from trackdb import LineNotFoundError, NoGeodeticPolylineError, parse_line
    from trackdb.geojson import line_geojson
    from trackdb.storage import export_line

    try:
        with _session(database) as session:
            document = export_line(session, line, version)
        if format is ExportFormat.GEOJSON:
            document = json.dumps(line_geojson(parse_line(document)), ensure_ascii=False)
    except (LineNotFoundError, NoGeodeticPolylineError) as exc:
        typer.echo(str(exc), err=True)
        raise typer.Exit(code=1) from exc
    if output is None:
        typer.echo(document)
    else:
        output.write_text(document, encoding="utf-8")


@trackdb_app.command("list")
def trackdb_list(database: DatabaseOption = None) -> None:
    """List the stored lines, tab-separated: id, current version, length in metres, name."""
    from trackdb.storage import list_lines

    with _session(database) as session:
        summaries = list_lines(session)
    for summary in summaries:
        typer.echo(f"{summary.id}\t{summary.version}\t{summary.length_m:.1f}\t{summary.name}")


@trackdb_app.command("seed")
def trackdb_seed(database: DatabaseOption = None) -> None:
    """Import each built-in line whose id is not stored (as the trackside does at start)."""
    from deploy.cli import _database_session
    from trackside.services.lines import ensure_seed_lines

    with _database_session(database) as session:
        imported = ensure_seed_lines(session)
    typer.echo(" ".join(imported) if imported else "built-in lines already stored")


@trackdb_app.command("schema")
def trackdb_schema() -> None:
    """Print the JSON Schema of a line document (as in trackdb/line.schema.json)."""
    from trackdb import line_json_schema

    typer.echo(line_json_schema(), nl=False)
