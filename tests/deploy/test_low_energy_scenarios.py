"""The Energy Manager's library scenarios (issue 22): `low-energy`, where the plan is slowed
within the arrival window and the journey finished, and `low-energy-short`, where not even that
suffices and the operator finds the warning before he engages; and the premise of both, that the
batteries really cannot finish the journey at the timetable's pace."""

from __future__ import annotations

from pathlib import Path

import pytest

from deploy.scenario import load_scenario, parse_scenario
from deploy.scenario.loader import SCENARIO_DIR
from deploy.scenario.runner import RunOptions, run_scenario
from deploy.scenario.vehicle_setup import onboard_settings


def test_the_vehicle_table_sets_the_range_extender_s_power(tmp_path: Path) -> None:
    spec = load_scenario("low-energy")
    assert spec.vehicle.range_extender_kw == 0.0
    settings = onboard_settings(spec, RunOptions(fast=True), 1, tmp_path)
    assert settings.range_extender_power_w == 0.0
    assert settings.initial_soc == spec.vehicle.initial_soc


def test_see_event_names_its_event_and_only_it() -> None:
    base = 'name = "x"\ntitle = "x"\nline = "bologna-ring"\nduration_s = 1.0\n'
    with pytest.raises(ValueError, match="event goes with see_event"):
        parse_scenario(base + '[[actions]]\ndo = "see_event"\n')
    with pytest.raises(ValueError, match="event goes with see_event"):
        parse_scenario(base + '[[actions]]\ndo = "engage"\nevent = "energy.insufficient"\n')


@pytest.mark.e2e
def test_low_energy_slows_the_plan_and_finishes_the_journey() -> None:
    kpis = run_scenario(load_scenario("low-energy"), RunOptions(fast=True)).kpis
    failed = [item for item in kpis.expectations if not item.ok]
    assert not failed, failed
    seen = [a for a in kpis.actions or [] if a.action == "see_event"]
    assert len(seen) == 1
    assert seen[0].detail is not None
    assert "end of its window" in seen[0].detail
    engaged = [a.at_s for a in kpis.actions or [] if a.action == "engage"]
    assert engaged
    assert seen[0].at_s <= engaged[0]
    assert [stop.name for stop in kpis.stops] == ["lodi"]


@pytest.mark.e2e
def test_at_the_timetable_s_pace_the_batteries_go_under_the_threshold() -> None:
    """`low-energy` with no arrival window, so no slower plan: the Energy Manager warns, the
    operator engages all the same, and the run goes under the VCU's charge-sustaining threshold
    that the slowed plan stays above (the reserve kept for a failed range extender)."""
    text = (SCENARIO_DIR / "low-energy.toml").read_text(encoding="utf-8")
    for old, new in (
        ("arrival_window_s = 300.0", "arrival_window_s = 0.0"),
        ('event = "energy.slower_profile"', 'event = "energy.insufficient"'),
    ):
        assert old in text
        text = text.replace(old, new)
    kpis = run_scenario(parse_scenario(text), RunOptions(fast=True)).kpis
    seen = [a for a in kpis.actions or [] if a.action == "see_event"]
    assert [a.accepted for a in seen] == [True]
    assert [stop.name for stop in kpis.stops] == ["lodi"]
    assert kpis.stops[0].planned_arrival_s == pytest.approx(1000.0)
    assert kpis.soc_min is not None
    floor = [e.value for e in load_scenario("low-energy").expect if e.kpi == "soc_min"]
    assert floor == [0.465]
    assert kpis.soc_min < 0.465


@pytest.mark.e2e
def test_low_energy_short_warns_the_operator_before_departure() -> None:
    kpis = run_scenario(load_scenario("low-energy-short"), RunOptions(fast=True)).kpis
    failed = [item for item in kpis.expectations if not item.ok]
    assert not failed, failed
    seen = [a for a in kpis.actions or [] if a.action == "see_event"]
    assert len(seen) == 1
    assert seen[0].detail is not None
    assert "do not engage" in seen[0].detail
    assert not [a for a in kpis.actions or [] if a.action == "engage"]
    assert kpis.stops == []
