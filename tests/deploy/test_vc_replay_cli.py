"""``ato vc replay FILE``: prints a datalog, filters by kind, refuses missing or corrupt files."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from deploy.cli import app
from onboard.vc.datalog import Datalog

runner = CliRunner()


def _datalog(path: Path) -> Path:
    with Datalog(path) as datalog:
        datalog.append(0.5, "vc.B", "eb_condition", {"detail": "2"})
        datalog.append(0.5, "vc.C", "eb_commanded", {"detail": "valves"})
    return path


def test_replay_prints_the_records(tmp_path: Path) -> None:
    result = runner.invoke(app, ["vc", "replay", str(_datalog(tmp_path / "vc.jsonl"))])
    assert result.exit_code == 0, result.output
    assert "eb_condition" in result.output
    assert "eb_commanded" in result.output
    assert "2 of 2 records" in result.output


def test_replay_filters_by_kind(tmp_path: Path) -> None:
    path = _datalog(tmp_path / "vc.jsonl")
    result = runner.invoke(app, ["vc", "replay", str(path), "--kind", "eb_commanded"])
    assert result.exit_code == 0, result.output
    assert "1 of 2 records" in result.output
    assert "eb_condition" not in result.output


def test_replay_reports_a_torn_last_line(tmp_path: Path) -> None:
    path = _datalog(tmp_path / "vc.jsonl")
    with path.open("a", encoding="utf-8") as file:
        file.write('{"seq":2,')
    result = runner.invoke(app, ["vc", "replay", str(path)])
    assert result.exit_code == 0, result.output
    assert "torn last line" in result.output


def test_replay_refuses_a_missing_file(tmp_path: Path) -> None:
    result = runner.invoke(app, ["vc", "replay", str(tmp_path / "nope.jsonl")])
    assert result.exit_code == 1
    assert "no such datalog" in result.output


def test_replay_refuses_a_corrupt_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.jsonl"
    path.write_text("garbage\n{}\n", encoding="utf-8")
    result = runner.invoke(app, ["vc", "replay", str(path)])
    assert result.exit_code == 1
    assert "corrupt datalog" in result.output
