"""Scenario files: the library loads; malformed files are rejected with their line and reason."""

from __future__ import annotations

from pathlib import Path

import pytest

from deploy.scenario import (
    ScenarioFileError,
    load_scenario,
    parse_condition,
    parse_scenario,
    scenario_names,
)

MINIMAL = """\
name = "tiny"
title = "A tiny scenario"
line = "bologna-ring"
duration_s = 10.0

[[actions]]
do = "rd_target_speed"
when = "etcs_mode == SR and standstill"
speed_kmh = 10.0
"""


def test_every_library_scenario_loads() -> None:
    names = scenario_names()
    assert "bologna-ring" in names
    for name in names:
        spec = load_scenario(name)
        assert spec.name == name


def test_a_minimal_scenario_parses_with_defaults() -> None:
    spec = parse_scenario(MINIMAL)
    assert spec.vehicle.id == "URV1"
    assert spec.vehicle.fidelity == "point_mass"
    assert spec.operator.simulated
    condition = spec.actions[0].condition
    assert condition is not None
    assert condition.holds({"etcs_mode": "SR", "standstill": True})
    assert not condition.holds({"etcs_mode": "FS", "standstill": True})


@pytest.mark.parametrize(
    ("text", "line", "reason"),
    [
        # TOML syntax: where the parser stopped.
        (MINIMAL + "speed_kmh = = 3\n", 10, "TOML"),
        # An unknown key, on its own line.
        (
            MINIMAL.replace('line = "bologna-ring"', 'line = "bologna-ring"\nlenght = 3'),
            4,
            "lenght: Extra inputs are not permitted",
        ),
        # A bad value inside the second array-of-tables entry.
        (MINIMAL + '\n[[actions]]\ndo = "engage"\nat_s = -1.0\n', 13, "actions.1.at_s"),
        # A condition that does not parse: the line of its `when`.
        (MINIMAL.replace("etcs_mode == SR", "etcs_mood == SR"), 8, "unknown field 'etcs_mood'"),
        # An unknown kind of fault: the line of its kind.
        (MINIMAL + '\n[[faults]]\nkind = "gps_outage"\n', 12, "does not match any"),
        # A missing key: the line of its table.
        (MINIMAL + '\n[[faults]]\nkind = "ato_failure"\n', 11, "start_s: Field required"),
        # A fault window that ends before it starts.
        (
            MINIMAL + '\n[[faults]]\nkind = "ato_failure"\nstart_s = 5\nend_s = 2\n',
            11,
            "end_s must be after start_s",
        ),
    ],
)
def test_malformed_files_are_rejected_with_line_and_reason(
    text: str, line: int, reason: str
) -> None:
    with pytest.raises(ScenarioFileError) as raised:
        parse_scenario(text, path="bad.toml")
    assert raised.value.line == line, str(raised.value)
    assert reason in raised.value.reason
    assert str(raised.value).startswith(f"bad.toml:{line}: ")


def test_unknown_names_and_unreadable_files_are_errors(tmp_path: Path) -> None:
    with pytest.raises(ScenarioFileError, match="no such scenario"):
        load_scenario("no-such-scenario")
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ScenarioFileError, match="cannot read it"):
        load_scenario(binary)


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("", "empty"),
        ("speed_kmh", "not a boolean"),
        ("standstill > 3", "true or false"),
        ("etcs_mode < FS", "only be compared"),
        ("speed_kmh < fast", "number"),
        ("not speed_kmh < 3", "'not' goes with a boolean"),
        ("import os", "cannot read"),
    ],
)
def test_bad_conditions_say_why(text: str, reason: str) -> None:
    with pytest.raises(ValueError, match=reason):
        parse_condition(text)


def test_a_zenoh_link_loss_has_a_window_and_a_mode() -> None:
    spec = load_scenario("zenoh-link-loss")
    (fault,) = spec.faults
    assert fault.kind == "zenoh_link_loss"
    assert (fault.start_s, fault.end_s, fault.mode) == (272.0, 306.0, "silent")
    text = MINIMAL + '\n[[faults]]\nkind = "zenoh_link_loss"\nstart_s = 5\nmode = "flaky"\n'
    with pytest.raises(ScenarioFileError, match="faults.0.zenoh_link_loss.mode"):
        parse_scenario(text, path="bad.toml")
