"""``ato trackdb``: import and export of lines, listing, and the JSON Schema."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from deploy.cli import app
from tests.trackdb.layouts import tiny_line
from trackdb import line_json_schema, load_seed_line

runner = CliRunner()


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
    listed = runner.invoke(app, ["trackdb", "list", "--database", database])
    assert listed.exit_code == 0
    assert listed.stdout == ""


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
    assert listed.stdout.split("\t")[:2] == ["tiny", tiny_line().version()]


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
    for name in ("import", "export", "list", "schema"):
        assert name in result.stdout
