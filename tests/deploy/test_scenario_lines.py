"""A scenario's line (deploy/scenario/line_source.py): a built-in line, a line stored in the
run's database, or a line file beside the scenario; bad ones are clear errors (``ato run`` exits
2) and reading leaves nothing behind; and a whole journey in lockstep on a line of a file."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from sqlalchemy.orm import Session
from typer.testing import CliRunner

from deploy.cli import app
from deploy.scenario import SCENARIO_DIR, ScenarioFileError, load_scenario, parse_scenario
from deploy.scenario.console import run_database_url, run_from_cli
from deploy.scenario.line_source import ScenarioLineError, resolve_line, stored_line
from deploy.scenario.runner import RunOptions, run_scenario
from tests.deploy.valley_line import valley_line
from trackdb import Line, load_seed_line, storage
from trackdb.railjson import line_from_railjson
from trackside.db import create_database_engine, migrate

HEADER = """\
name = "on-a-file"
title = "A scenario on a line of its own"
duration_s = 10.0
"""

JOURNEY = """
end_when = "journey_ended and standstill"

[vehicle]
start_position_m = 100.0

[journey]
id = "valley-journey"
max_speed_kmh = 60.0

[[journey.timing_points]]
id = "a"
stopping_point_id = "a"
arrival_time_s = 150.0
departure_time_s = 170.0

[[journey.timing_points]]
id = "b"
stopping_point_id = "b"
arrival_time_s = 330.0
departure_time_s = 350.0

[[journey.timing_points]]
id = "c"
stopping_point_id = "c"
arrival_time_s = 530.0
end_of_journey = true

[[actions]]
do = "issue_ma"
when = "not vc_eb"
end_of_authority_m = 3150.0

[[actions]]
do = "send_journey"
when = "etcs_mode == FS and standstill"

[[actions]]
do = "engage"
when = "ato_state == RE"

[[expect]]
kpi = "stops.count"
op = "=="
value = 3

[[expect]]
kpi = "stops.stop_error_m"
op = "abs<="
value = 0.5

[[expect]]
kpi = "max_overspeed_kmh"
op = "<="
value = 0.0

[[expect]]
kpi = "etcs_sb_count"
op = "=="
value = 0

[[expect]]
kpi = "etcs_eb_count"
op = "=="
value = 0

[[expect]]
kpi = "vc_eb_count"
op = "=="
value = 0
"""


def _write(directory: Path, name: str, text: str) -> Path:
    path = directory / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def _database(directory: Path, *lines: Line) -> str:
    """A migrated SQLite database holding ``lines``; its URL."""
    url = f"sqlite:///{directory / 'user.db'}"
    engine = create_database_engine(url)
    try:
        migrate(engine)
        with Session(engine) as session, session.begin():
            for line in lines:
                storage.import_line(session, line)
    finally:
        engine.dispose()
    return url


# -- the file's keys ---------------------------------------------------------------------------


def test_a_line_file_is_taken_relative_to_the_scenario_file(tmp_path: Path) -> None:
    line = valley_line()
    _write(tmp_path / "lines", "valley.json", line.model_dump_json())
    scenario = _write(
        tmp_path / "scenarios", "s.toml", HEADER + 'line_file = "../lines/valley.json"\n'
    )
    spec = load_scenario(scenario)
    assert spec.line is None
    assert Path(spec.line_file or "") == tmp_path / "scenarios" / "../lines/valley.json"
    resolved = resolve_line(spec)
    assert resolved == line
    assert resolved.version() == line.version()


@pytest.mark.parametrize(
    ("keys", "line", "reason"),
    [
        ('line = "bologna-ring"\nline_file = "x.json"\n', None, "one of the two"),
        ("", None, "one of the two"),
        (
            'line = "bologna-ring"\n\n[line_import]\nformat = "railjson"\nfrom = "A"\nto = "B"\n'
            'id = "x"\n',
            None,
            "[line_import] goes with line_file",
        ),
        (
            'line_file = "x.json"\n\n[line_import]\nformat = "railml"\nfrom = "A"\nto = "B"\n'
            'id = "x"\n',
            7,
            "line_import.format",
        ),
        (
            'line_file = "x.json"\n\n[line_import]\nformat = "railjson"\nto = "B"\nid = "x"\n',
            6,
            "from",
        ),
        (
            'line_file = "x.json"\n\n[line_import]\nformat = "railjson"\nfrom = "A"\nto = "B"\n'
            'id = "not an id"\n',
            10,
            "line_import.id",
        ),
        ('line = "no spaces allowed"\n', 4, "line: String should match"),
    ],
)
def test_the_line_keys_are_checked_with_their_line(
    keys: str, line: int | None, reason: str
) -> None:
    with pytest.raises(ScenarioFileError) as raised:
        parse_scenario(HEADER + keys, path="bad.toml")
    assert reason in raised.value.reason, raised.value.reason
    if line is not None:
        assert raised.value.line == line, str(raised.value)


def test_a_railjson_import_table_reads_like_the_command_line() -> None:
    spec = parse_scenario(
        HEADER + 'line_file = "infra.json"\n\n[line_import]\nformat = "railjson"\n'
        'from = "West"\nto = "East"\nvia = ["Middle"]\nid = "west-east"\nname = "West to East"\n'
    )
    options = spec.line_import
    assert options is not None
    assert (options.from_op, options.to_op, options.via) == ("West", "East", ("Middle",))
    assert (options.id, options.name) == ("west-east", "West to East")
    # The scenario writes back with the file's own keys (generated scenarios round-trip).
    assert spec.model_dump(mode="json")["line_import"]["from"] == "West"


# -- stored lines ------------------------------------------------------------------------------


def test_built_in_lines_come_first_then_the_runs_database(tmp_path: Path) -> None:
    own = valley_line()
    # A database that also holds another version of a built-in id: the shipped line is used.
    url = _database(tmp_path, own, valley_line("bologna-ring"))
    assert stored_line("bologna-ring", database_url=url) == load_seed_line("bologna-ring")
    assert stored_line("valley-test", database_url=url) == own
    spec = parse_scenario(HEADER + 'line = "valley-test"\n')
    assert resolve_line(spec, database_url=url) == own


def test_an_unknown_line_names_where_it_was_looked_for(tmp_path: Path) -> None:
    url = _database(tmp_path)
    with pytest.raises(ScenarioLineError, match="nor stored in sqlite:///"):
        stored_line("valley-test", database_url=url)
    with pytest.raises(ScenarioLineError, match="not a built-in line"):
        stored_line("valley-test")
    missing = tmp_path / "absent" / "none.db"
    with pytest.raises(ScenarioLineError, match="no database at"):
        stored_line("valley-test", database_url=f"sqlite:///{missing}")
    assert not missing.parent.exists()


def test_ato_run_reads_stored_lines_where_the_trackside_does(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv("ATO_DATABASE_URL", raising=False)
    assert run_database_url() == "sqlite:///ato.db"
    monkeypatch.setenv("ATO_DATABASE_URL", "postgresql://ato@db/ato")
    assert run_database_url() == "postgresql://ato@db/ato"


# -- bad line files ----------------------------------------------------------------------------


def _bad_files(directory: Path) -> dict[str, tuple[Path, str]]:
    good = json.loads(valley_line().model_dump_json())
    broken = dict(good, length_m=-5.0)
    return {
        "missing": (directory / "absent.json", "cannot read it"),
        "not json": (_write(directory, "text.json", "not json at all"), "not a valid line"),
        "schema": (_write(directory, "schema.json", json.dumps(broken)), "length_m"),
        "a directory": (directory, "cannot read it"),
    }


@pytest.mark.parametrize("case", ["missing", "not json", "schema", "a directory"])
def test_a_bad_line_file_is_a_scenario_error(tmp_path: Path, case: str) -> None:
    path, reason = _bad_files(tmp_path / "lines")[case]
    spec = parse_scenario(HEADER + f'line_file = "{path}"\n')
    with pytest.raises(ScenarioLineError) as raised:
        resolve_line(spec)
    assert str(raised.value).startswith(f"line_file {path}: ")
    assert reason in str(raised.value)


def test_ato_run_exits_2_on_a_bad_line_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _write(tmp_path, "broken.json", '{"id": "broken"}')
    scenario = _write(tmp_path, "s.toml", HEADER + 'line_file = "broken.json"\n')
    status = run_from_cli(str(scenario), fast=True, speed=1.0, seed=None, report=None)
    assert status == 2
    error = "".join(capsys.readouterr().err.split())  # rich may wrap it anywhere
    assert "cannotrunon-a-file" in error
    assert "broken.json" in error
    assert "notavalidline" in error


# -- RailJSON ----------------------------------------------------------------------------------

RAILJSON = SCENARIO_DIR.parent / "lines" / "junction-valley.railjson.json"


def _railjson_scenario(to: str = "eastfield") -> str:
    return HEADER + (
        f'line_file = "{RAILJSON}"\n\n[line_import]\nformat = "railjson"\nfrom = "westbrook"\n'
        f'to = "{to}"\nvia = ["millbridge", "valley-junction"]\nid = "junction-valley"\n'
    )


def test_the_library_railjson_scenario_builds_the_line_the_import_builds() -> None:
    spec = load_scenario("railjson-junction-valley")
    assert Path(spec.line_file or "").resolve() == RAILJSON.resolve()
    line = resolve_line(spec)
    expected = line_from_railjson(
        RAILJSON.read_bytes(),
        from_op="westbrook",
        to_op="eastfield",
        via=["millbridge", "valley-junction"],
        line_id="junction-valley",
        name="Junction Valley: Westbrook – Eastfield",
    )
    assert line.version() == expected.version()
    stops = {point.id for point in line.stopping_points}
    assert {
        tp.stopping_point_id for tp in (spec.journey.timing_points if spec.journey else ())
    } <= stops
    assert spec.vehicle.start_position_m == pytest.approx(
        next(p.position_m for p in line.stopping_points if p.id == "westbrook")
    )


def test_a_railjson_error_names_the_file_and_the_place_in_it() -> None:
    with pytest.raises(ScenarioLineError) as raised:
        resolve_line(parse_scenario(_railjson_scenario(to="nowhere")))
    message = str(raised.value)
    assert message.startswith(f"line_file {RAILJSON}: RailJSON: $.operational_points: ")
    assert "'nowhere'" in message


def test_a_document_that_is_not_railjson_is_a_scenario_error(tmp_path: Path) -> None:
    _write(tmp_path, "infra.json", json.dumps({"version": "2.0.0"}))
    text = _railjson_scenario().replace(str(RAILJSON), "infra.json")
    scenario = _write(tmp_path, "s.toml", text)
    with pytest.raises(ScenarioLineError, match=r"infra.json: RailJSON: \$"):
        resolve_line(load_scenario(scenario))


# -- whole runs -------------------------------------------------------------------------------


@pytest.mark.e2e
def test_a_journey_on_a_line_file_stops_within_half_a_metre(tmp_path: Path) -> None:
    """The vehicle drives on the file's line, and the run's trackside plans on that same line
    (it holds it in its database: the journey and the MA name it)."""
    _write(tmp_path, "valley.json", valley_line().model_dump_json())
    text = HEADER.replace("duration_s = 10.0", "duration_s = 900.0") + 'line_file = "valley.json"\n'
    scenario = _write(tmp_path, "valley.toml", text + JOURNEY)
    outcome = run_scenario(load_scenario(scenario), RunOptions(fast=True))
    kpis = outcome.kpis
    assert outcome.passed, [e for e in kpis.expectations if not e.ok]
    assert [stop.name for stop in kpis.stops] == ["a", "b", "c"]
    assert all(abs(stop.stop_error_m) <= 0.5 for stop in kpis.stops)


@pytest.mark.e2e
def test_ato_run_on_the_railjson_line_stops_at_both_intermediate_stops(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 21's must-show: ``ato run railjson-junction-valley --fast`` on the line imported
    from the RailJSON test infrastructure: two intermediate stops and the last, each within
    0.5 m, no overspeed, no ETCS or VC intervention."""
    status = run_from_cli(
        "railjson-junction-valley", fast=True, speed=1.0, seed=None, report=tmp_path
    )
    kpis = json.loads((tmp_path / "kpis.json").read_text())
    assert status == 0, [e for e in kpis["expectations"] if not e["ok"]]
    assert kpis["passed"]
    assert [stop["name"] for stop in kpis["stops"]] == [
        "millbridge",
        "valley-junction",
        "eastfield",
    ]
    assert all(abs(stop["stop_error_m"]) <= 0.5 for stop in kpis["stops"])
    assert kpis["max_overspeed_kmh"] <= 0.0
    assert kpis["etcs_sb_count"] == kpis["etcs_eb_count"] == kpis["vc_eb_count"] == 0
    assert "railjson-junction-valley: PASSED" in capsys.readouterr().out


def test_ato_run_reads_a_stored_line_from_its_database_option(tmp_path: Path) -> None:
    scenario = _write(tmp_path, "s.toml", HEADER + 'line = "valley-test"\n')
    missing = tmp_path / "absent" / "none.db"
    result = CliRunner().invoke(app, ["run", str(scenario), "--database", f"sqlite:///{missing}"])
    assert result.exit_code == 2
    output = "".join(result.output.split())  # rich may wrap it anywhere
    assert "nodatabaseat" in output
    assert str(missing) in output
