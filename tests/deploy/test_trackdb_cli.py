"""``ato trackdb``: import (ours and RailJSON) and export (ours and GeoJSON) of lines, listing,
seeding the built-in lines, and the JSON Schema."""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import create_engine, inspect, select
from typer.testing import CliRunner

from deploy.cli import app
from tests.trackdb.layouts import tiny_line
from tests.trackdb.railjson_builder import junction_valley
from trackdb import SEED_LINES, line_json_schema, load_seed_line
from trackdb.railjson import MAX_DOCUMENT_BYTES
from trackdb.storage import LineVersionRow

runner = CliRunner()
REPOSITORY = Path(__file__).resolve().parents[2]
JUNCTION_VALLEY = REPOSITORY / "deploy" / "lines" / "junction-valley.railjson.json"
JUNCTION_VALLEY_ARGS = ["--format", "railjson", "--from", "westbrook", "--to", "eastfield"]


def stored(database: str) -> list[tuple[str, str]]:
    """Every (line id, version) in the database, read around the CLI; [] if it has no tables."""
    engine = create_engine(database)
    try:
        if not inspect(engine).has_table("line_versions"):
            return []
        with engine.connect() as connection:
            rows = connection.execute(select(LineVersionRow.line_id, LineVersionRow.version))
            return sorted((row[0], row[1]) for row in rows)
    finally:
        engine.dispose()


def seeded(database: str) -> list[tuple[str, str]]:
    """A database that holds the built-in lines (the first command seeds them)."""
    assert runner.invoke(app, ["trackdb", "list", "--database", database]).exit_code == 0
    return stored(database)


@pytest.mark.parametrize("line_id", ["bologna-ring", "milano-bologna"])
def test_import_then_export_keeps_the_version(
    line_id: str, tmp_path: Path, database_url: str
) -> None:
    line = load_seed_line(line_id)
    source = tmp_path / f"{line_id}.json"
    source.write_text(line.model_dump_json(indent=2), encoding="utf-8")
    imported = runner.invoke(app, ["trackdb", "import", str(source), "--database", database_url])
    assert imported.exit_code == 0, imported.output
    assert imported.stdout.split() == [line_id, line.version()]

    exported = runner.invoke(app, ["trackdb", "export", line_id, "--database", database_url])
    assert exported.exit_code == 0, exported.output
    assert exported.stdout == line.model_dump_json(round_trip=True) + "\n"

    target = tmp_path / "out" / "exported.json"
    target.parent.mkdir()
    to_file = runner.invoke(
        app, ["trackdb", "export", line_id, "--database", database_url, "--output", str(target)]
    )
    assert to_file.exit_code == 0
    assert to_file.stdout == ""
    assert hashlib.sha256(target.read_bytes()).hexdigest() == line.version()

    again = runner.invoke(app, ["trackdb", "import", str(target), "--database", database_url])
    assert again.stdout.split() == [line_id, line.version()]


def test_an_invalid_file_exits_2_listing_every_problem(tmp_path: Path) -> None:
    document = tiny_line().model_dump(mode="json")
    document["speed_limit_mps"][0]["value"] = -3.0
    document["stopping_points"][0]["position_m"] = 9999.0
    source = tmp_path / "broken.json"
    source.write_text(json.dumps(document), encoding="utf-8")
    database = f"sqlite:///{tmp_path / 'ato.db'}"
    result = runner.invoke(app, ["trackdb", "import", str(source), "--database", database])
    assert result.exit_code == 2
    lines = result.stderr.splitlines()
    assert "2 problem(s)" in lines[0]
    assert any(line.startswith("speed_limit_mps[0]") for line in lines[1:])
    assert any(line.startswith("stopping_points[0]") for line in lines[1:])
    assert result.stdout == ""
    assert stored(database) == []  # not even the built-in lines: the transaction rolled back


def test_a_file_that_is_not_json_exits_2(tmp_path: Path) -> None:
    source = tmp_path / "notes.txt"
    source.write_text("not a line", encoding="utf-8")
    database = f"sqlite:///{tmp_path / 'ato.db'}"
    result = runner.invoke(app, ["trackdb", "import", str(source), "--database", database])
    assert result.exit_code == 2
    assert "Invalid JSON" in result.stderr


def test_the_database_defaults_to_ato_database_url(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ATO_DATABASE_URL", f"sqlite:///{tmp_path / 'from-env.db'}")
    source = tmp_path / "tiny.json"
    source.write_text(tiny_line().model_dump_json(), encoding="utf-8")
    assert runner.invoke(app, ["trackdb", "import", str(source)]).exit_code == 0
    assert (tmp_path / "from-env.db").exists()
    listed = runner.invoke(app, ["trackdb", "list"])
    rows = [row.split("\t")[:2] for row in listed.stdout.splitlines()]
    assert ["tiny", tiny_line().version()] in rows


def test_exporting_an_unknown_line_fails(tmp_path: Path) -> None:
    database = f"sqlite:///{tmp_path / 'ato.db'}"
    result = runner.invoke(app, ["trackdb", "export", "nowhere", "--database", database])
    assert result.exit_code == 1
    assert "nowhere" in result.stderr


def test_schema_prints_the_committed_json_schema() -> None:
    result = runner.invoke(app, ["trackdb", "schema"])
    assert result.exit_code == 0
    assert result.stdout == line_json_schema()


def test_trackdb_is_listed_in_help() -> None:
    result = runner.invoke(app, ["trackdb", "--help"])
    assert result.exit_code == 0
    for name in ("import", "export", "list", "schema", "seed"):
        assert name in result.stdout


# Built-in lines


def test_a_fresh_database_exports_the_built_in_lines(tmp_path: Path) -> None:
    database = f"sqlite:///{tmp_path / 'fresh.db'}"
    exported = runner.invoke(app, ["trackdb", "export", "bologna-ring", "--database", database])
    assert exported.exit_code == 0, exported.output
    assert exported.stdout == load_seed_line("bologna-ring").model_dump_json(round_trip=True) + "\n"
    assert {line_id for line_id, _ in stored(database)} == set(SEED_LINES)


def test_seed_imports_the_missing_built_ins_and_keeps_the_rest(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ATO_SEED_LINES", "false")
    database = f"sqlite:///{tmp_path / 'ato.db'}"
    source = tmp_path / "tiny.json"
    source.write_text(tiny_line().model_dump_json(), encoding="utf-8")
    assert (
        runner.invoke(app, ["trackdb", "import", str(source), "--database", database]).exit_code
        == 0
    )
    assert stored(database) == [("tiny", tiny_line().version())]
    seeded_now = runner.invoke(app, ["trackdb", "seed", "--database", database])
    assert seeded_now.exit_code == 0
    assert seeded_now.stdout.split() == list(SEED_LINES)
    again = runner.invoke(app, ["trackdb", "seed", "--database", database])
    assert again.stdout.strip() == "built-in lines already stored"
    assert {line_id for line_id, _ in stored(database)} == {"tiny", *SEED_LINES}


# RailJSON import


def test_junction_valley_imports_between_two_operational_points(tmp_path: Path) -> None:
    database = f"sqlite:///{tmp_path / 'ato.db'}"
    result = runner.invoke(
        app,
        [
            "trackdb",
            "import",
            str(JUNCTION_VALLEY),
            *JUNCTION_VALLEY_ARGS,
            "--id",
            "junction-valley",
        ]
        + ["--database", database],
    )
    assert result.exit_code == 0, result.output
    line_id, version = result.stdout.split()
    assert line_id == "junction-valley"
    assert ("junction-valley", version) in stored(database)
    for stop in ("westbrook", "millbridge", "valley-junction", "eastfield"):
        assert f"stopping point {stop} at" in result.stderr
    exported = runner.invoke(app, ["trackdb", "export", "junction-valley", "--database", database])
    assert hashlib.sha256(exported.stdout.rstrip("\n").encode()).hexdigest() == version
    document = json.loads(exported.stdout)
    assert document["name"] == "Westbrook – Eastfield"
    assert document["etcs_level"] == 2


def test_the_geojson_export_has_the_polyline_and_the_stopping_points(tmp_path: Path) -> None:
    database = f"sqlite:///{tmp_path / 'ato.db'}"
    imported = runner.invoke(
        app,
        ["trackdb", "import", str(JUNCTION_VALLEY), *JUNCTION_VALLEY_ARGS, "--via", "millbridge"]
        + ["--id", "jv", "--name", "Junction valley", "--database", database],
    )
    assert imported.exit_code == 0, imported.output
    target = tmp_path / "jv.geojson"
    exported = runner.invoke(
        app,
        [
            "trackdb",
            "export",
            "jv",
            "--format",
            "geojson",
            "-o",
            str(target),
            "--database",
            database,
        ],
    )
    assert exported.exit_code == 0, exported.output
    collection = json.loads(target.read_text(encoding="utf-8"))
    assert collection["type"] == "FeatureCollection"
    line, *stops = collection["features"]
    assert line["geometry"]["type"] == "LineString"
    assert line["properties"]["name"] == "Junction valley"
    longitude, latitude, _ = line["geometry"]["coordinates"][0]
    assert 7.3 < longitude < 7.5
    assert 46.1 < latitude < 46.3
    assert [stop["properties"]["id"] for stop in stops] == [
        "westbrook",
        "millbridge",
        "valley-junction",
        "eastfield",
    ]
    assert all(stop["geometry"]["type"] == "Point" for stop in stops)
    assert stops[0]["properties"]["chainage_m"] == pytest.approx(300.0, abs=1e-6)


def _bad(document: dict[str, Any], tmp_path: Path) -> Path:
    source = tmp_path / "bad.railjson.json"
    source.write_text(json.dumps(document), encoding="utf-8")
    return source


def _refused(source: Path, database: str, *options: str) -> str:
    """Imports ``source`` into a seeded database: exit 2, nothing stored; the error line."""
    before = seeded(database)
    options = options or (*JUNCTION_VALLEY_ARGS, "--id", "jv")
    result = runner.invoke(
        app, ["trackdb", "import", str(source), *options, "--database", database]
    )
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    assert stored(database) == before
    return result.stderr.strip()


def _between(origin: str, destination: str) -> list[str]:
    return ["--format", "railjson", "--from", origin, "--to", destination, "--id", "jv"]


def test_an_unknown_operational_point_exits_2(tmp_path: Path) -> None:
    database = f"sqlite:///{tmp_path / 'ato.db'}"
    message = _refused(JUNCTION_VALLEY, database, *_between("westbrook", "nowhere"))
    assert message == (
        f"{JUNCTION_VALLEY}: $.operational_points: no operational point 'nowhere' (given with --to)"
    )


def test_no_path_exits_2(tmp_path: Path) -> None:
    database = f"sqlite:///{tmp_path / 'ato.db'}"
    # Northgate's branch leaves the main line eastwards: from Eastfield only a reversal reaches it.
    message = _refused(JUNCTION_VALLEY, database, *_between("eastfield", "northgate"))
    index = [op["id"] for op in junction_valley().build()["operational_points"]].index("northgate")
    assert f": $.operational_points[{index}]: no path from 'eastfield' to 'northgate'" in message


def test_an_unsupported_version_exits_2(tmp_path: Path) -> None:
    document = junction_valley().build() | {"version": "2.2.0"}
    message = _refused(_bad(document, tmp_path), f"sqlite:///{tmp_path / 'ato.db'}")
    assert message.endswith(
        "$.version: unsupported RailJSON version '2.2.0': this import reads versions 3.x"
    )


def test_inconsistent_ranges_exit_2(tmp_path: Path) -> None:
    document = junction_valley().build()
    index = [t["id"] for t in document["track_sections"]].index("main-02")
    document["track_sections"][index]["slopes"][0]["end"] = 2000.0
    message = _refused(_bad(document, tmp_path), f"sqlite:///{tmp_path / 'ato.db'}")
    assert message.endswith(
        f"$.track_sections[{index}].slopes[0]: range 0.0..2000.0 m beyond the track section's "
        "length 900.0 m"
    )


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (b"{not json", ": $: not JSON: "),
        (b"[1, 2]", ": $: a JSON object expected, not list"),
    ],
)
def test_a_malformed_file_exits_2(tmp_path: Path, content: bytes, expected: str) -> None:
    source = tmp_path / "malformed.json"
    source.write_bytes(content)
    assert expected in _refused(source, f"sqlite:///{tmp_path / 'ato.db'}")


def test_wrong_types_exit_2(tmp_path: Path) -> None:
    document = junction_valley().build()
    document["track_sections"][12]["length"] = "long"
    message = _refused(_bad(document, tmp_path), f"sqlite:///{tmp_path / 'ato.db'}")
    assert message.endswith(
        "$.track_sections[12].length: Input should be a valid number, unable to parse string "
        "as a number"
    )


def test_a_document_over_the_size_limit_is_refused_unread(tmp_path: Path) -> None:
    source = tmp_path / "huge.railjson.json"
    with source.open("wb") as sparse:  # no data written: the limit is checked before reading
        sparse.truncate(MAX_DOCUMENT_BYTES + 1)
    assert os.path.getsize(source) == MAX_DOCUMENT_BYTES + 1
    message = _refused(source, f"sqlite:///{tmp_path / 'ato.db'}")
    assert message.endswith(
        f"$: document of {MAX_DOCUMENT_BYTES + 1} bytes over the limit of {MAX_DOCUMENT_BYTES} "
        "bytes (64 MiB)"
    )


def test_railjson_needs_from_to_and_id() -> None:
    result = runner.invoke(
        app,
        ["trackdb", "import", str(JUNCTION_VALLEY), "--format", "railjson", "--from", "westbrook"],
    )
    assert result.exit_code == 2
    assert "--format railjson needs --to, --id" in result.stderr


@pytest.mark.parametrize("railjson", [False, True])
def test_a_missing_file_exits_2(tmp_path: Path, railjson: bool) -> None:
    options = [*JUNCTION_VALLEY_ARGS, "--id", "jv"] if railjson else []
    missing = tmp_path / "missing.json"
    result = runner.invoke(app, ["trackdb", "import", str(missing), *options])
    assert result.exit_code == 2
    assert result.stderr.startswith(f"{missing}: ")
    assert "No such file" in result.stderr
