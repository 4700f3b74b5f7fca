"""RBC scenario scripts: loading (YAML, JSON, TOML), clear errors, deterministic execution."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest

from protocol import messages as m
from tests.conftest import wait_for
from trackside.errors import RbcScenarioError
from trackside.rbc import RbcEmulator
from trackside.rbc_scenario import (
    RbcScenarioRunner,
    RbcScenarioThread,
    load_scenario,
    parse_scenario,
)

SCRIPT_YAML = """
name: first-lap
actions:
  - {at_s: 0, vehicle: URV1, action: issue, line_id: milano-bologna, line_version: v1,
     start_m: 0, end_of_authority_m: 800, overlap_m: 50}
  - {at_s: 30, vehicle: URV1, action: shorten, end_of_authority_m: 600}
  - {at_s: 10, vehicle: URV1, action: extend, end_of_authority_m: 1500}
  - {at_s: 10, vehicle: URV2, action: issue, line_id: milano-bologna, line_version: v1,
     start_m: 5000, end_of_authority_m: 5200}
  - {at_s: 40, vehicle: URV2, action: shorten, end_of_authority_m: 6000}
  - {at_s: 50, vehicle: URV1, action: revoke}
"""


class Clock:
    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


def _run_lockstep(script: str, period_s: float = 0.1) -> list[tuple[float, str, str, int]]:
    clock = Clock()
    rbc = RbcEmulator(clock=clock)
    sent: list[tuple[float, str, str, int]] = []
    rbc.add_listener(
        lambda msg: sent.append((msg.issued_at_s, msg.vehicle_id, msg.change.value, msg.ma_id))
    )
    runner = RbcScenarioRunner(parse_scenario(script), rbc)
    tick = 0
    while not runner.done:
        runner.step()
        tick += 1
        clock.now_s = tick * period_s
    refused = [o for o in runner.outcomes if o.error is not None]
    assert [(o.index, o.action.vehicle) for o in refused] == [(4, "URV2")]
    assert refused[0].error is not None
    assert "must move the EoA back" in refused[0].error
    return sent


def test_actions_run_in_time_order_against_the_clock() -> None:
    sent = _run_lockstep(SCRIPT_YAML)
    assert [(round(t, 6), v, c, i) for t, v, c, i in sent] == [
        (0.0, "URV1", "issued", 1),
        (10.0, "URV1", "extended", 2),
        (10.0, "URV2", "issued", 1),
        (30.0, "URV1", "shortened", 3),
        (50.0, "URV1", "revoked", 4),
    ]


def test_the_same_script_gives_the_same_messages() -> None:
    assert _run_lockstep(SCRIPT_YAML) == _run_lockstep(SCRIPT_YAML)


def test_runner_start_and_next_due() -> None:
    clock = Clock()
    clock.now_s = 100.0
    rbc = RbcEmulator(clock=clock)
    runner = RbcScenarioRunner(parse_scenario(SCRIPT_YAML), rbc)
    assert runner.start_s == 100.0
    assert runner.next_due_s == 100.0
    assert [o.action.action for o in runner.step()] == ["issue"]
    assert runner.next_due_s == 110.0
    clock.now_s = 109.9
    assert runner.step() == []
    clock.now_s = 110.0
    assert len(runner.step()) == 2
    current = rbc.current("URV1")
    assert current is not None
    assert current.change is m.MovementAuthorityChange.EXTENDED


def test_yaml_json_and_toml_files_load_alike(tmp_path: Path) -> None:
    scenario = parse_scenario(SCRIPT_YAML)
    document = scenario.model_dump(mode="json", exclude_defaults=True)
    (tmp_path / "s.yaml").write_text(SCRIPT_YAML)
    (tmp_path / "s.json").write_text(json.dumps(document))
    toml_actions = "\n".join(
        "[[actions]]\n" + "\n".join(f"{key} = {json.dumps(value)}" for key, value in a.items())
        for a in document["actions"]
    )
    (tmp_path / "s.toml").write_text(f'name = "first-lap"\n{toml_actions}\n')
    for name in ("s.yaml", "s.json", "s.toml"):
        assert load_scenario(tmp_path / name) == scenario


@pytest.mark.parametrize(
    ("script", "needles"),
    [
        (
            "actions:\n  - {at_s: 0, vehicle: URV1, action: extend}\n"
            "  - {at_s: -1, vehicle: URV1, action: revoke}\n"
            "  - {at_s: 2, vehicle: URV1, action: teleport}\n"
            "  - {at_s: x, vehicle: 'a b', action: revoke, speed: 3}\n",
            [
                "6 problem(s)",
                "actions[0].end_of_authority_m: Field required",
                "actions[1].at_s: Input should be greater than or equal to 0 (got -1)",
                "actions[2]: Input tag 'teleport'",
                "actions[3].at_s: Input should be a valid number",
                "(got 'x')",
                "actions[3].vehicle: String should match pattern",
                "actions[3].speed: Extra inputs are not permitted",
            ],
        ),
        (
            "actions:\n  - {at_s: 0, vehicle: URV1, action: issue, line_id: l, start_m: 900,"
            " end_of_authority_m: 800}\n",
            ["actions[0]: the EoA (800.0 m) must lie beyond the start (900.0 m)"],
        ),
        ("actions: []\n", ["actions: a scenario needs at least one action"]),
        ("[1, 2]\n", ["scenario: Input should be a valid dictionary"]),
        ("actions: [\n", ["not valid YAML"]),
    ],
)
def test_bad_scripts_list_every_problem_with_its_place(script: str, needles: list[str]) -> None:
    with pytest.raises(RbcScenarioError) as caught:
        parse_scenario(script, source="bad.yaml")
    text = str(caught.value)
    assert text.startswith("bad.yaml: ")
    for needle in needles:
        assert needle in text, text


def test_unreadable_and_unknown_files(tmp_path: Path) -> None:
    with pytest.raises(RbcScenarioError, match="cannot read"):
        load_scenario(tmp_path / "missing.yaml")
    (tmp_path / "s.txt").write_text("actions: []")
    with pytest.raises(RbcScenarioError, match="unknown RBC scenario format '.txt'"):
        load_scenario(tmp_path / "s.txt")
    (tmp_path / "s.json").write_text("{")
    with pytest.raises(RbcScenarioError, match="not valid JSON"):
        load_scenario(tmp_path / "s.json")
    (tmp_path / "s.toml").write_text("actions = [")
    with pytest.raises(RbcScenarioError, match="not valid TOML"):
        load_scenario(tmp_path / "s.toml")


def test_thread_runs_a_script_until_done() -> None:
    clock = Clock()
    rbc = RbcEmulator(clock=clock)
    done = threading.Event()
    rbc.add_listener(lambda msg: done.set() if msg.change.value == "revoked" else None)
    thread = RbcScenarioThread(RbcScenarioRunner(parse_scenario(SCRIPT_YAML), rbc), period_s=0.001)
    clock.now_s = 60.0
    assert done.wait(5.0)
    assert wait_for(lambda: thread.runner.done)
    thread.close()
    assert rbc.last_ma_id("URV1") == 4
