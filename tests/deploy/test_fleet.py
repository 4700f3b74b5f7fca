"""Multi-train scenarios (issue 23): the ``[[trains]]`` schema, the truth's distances and
headways of a fleet run, and expectations on the ``fleet`` block of ``kpis.json``."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

import deploy.scenario
from deploy.scenario import ScenarioFileError, load_scenario, parse_scenario
from deploy.scenario.fleet import headways_at_stops, nearest_ahead, train_specs
from deploy.scenario.kpis import kpi_value
from deploy.scenario.runner import RunOptions, run_scenario
from deploy.scenario.telemetry import StopRecord
from tests.deploy.kpi_samples import sample_kpis

SCENARIOS = Path(deploy.scenario.__file__).resolve().parents[1] / "scenarios"
TWO_TRAINS = """\
name = "pair"
title = "Two trains"
line = "bologna-ring-l2"
duration_s = 10.0

[separation]
margin_m = 50.0

[vehicle]
id = "URV1"
start_position_m = 600.0

[[trains]]
vehicle = { id = "URV2", start_position_m = 300.0 }

[[trains.actions]]
do = "issue_ma"
when = "not vc_eb"
end_of_authority_m = 250.0
"""


def test_a_two_train_scenario_gives_each_train_its_own_run() -> None:
    spec = parse_scenario(TWO_TRAINS)
    lead, follower = train_specs(spec)
    assert (lead.vehicle.id, follower.vehicle.id) == ("URV1", "URV2")
    assert follower.vehicle.start_position_m == 300.0
    assert follower.actions[0].do == "issue_ma"
    # The line, the duration and the end condition are the run's; neither is a fleet again.
    assert follower.line == lead.line == "bologna-ring-l2"
    assert follower.duration_s == 10.0
    assert not lead.trains
    assert not follower.trains
    assert lead.separation is None
    assert follower.separation is None


@pytest.mark.parametrize(
    ("name", "trains"),
    [
        ("two-trains-following", ["URV1", "URV2"]),
        ("train-stalls-ahead", ["URV1", "URV2"]),
        ("three-trains-ring", ["URV1", "URV2", "URV3"]),
    ],
)
def test_the_library_s_multi_train_scenarios_load(name: str, trains: list[str]) -> None:
    spec = load_scenario(name)
    assert [t.vehicle.id for t in train_specs(spec)] == trains
    assert spec.separation is not None
    assert spec.separation.margin_m == 50.0


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        (lambda t: t.replace('id = "URV1"', 'id = "URV2"'), "each train has its own vehicle id"),
        (lambda t: t.replace("[separation]\nmargin_m = 50.0\n", ""), "[separation]"),
        (
            lambda t: t + '\n[[faults]]\nkind = "trackside_restart"\nat_s = 5.0\n',
            "trackside_restart",
        ),
        (lambda t: t.replace("margin_m = 50.0", "margin_m = -1.0"), "margin_m"),
    ],
)
def test_malformed_fleets_are_refused(change: object, reason: str) -> None:
    text = change(TWO_TRAINS)  # type: ignore[operator]
    with pytest.raises(ScenarioFileError) as raised:
        parse_scenario(text)
    assert "".join(reason.split()) in "".join(str(raised.value).split())


def test_the_nearest_train_ahead_wraps_on_a_ring_and_not_on_an_open_line() -> None:
    fronts = [600.0, 300.0, 5600.0]
    # On a 5700 m ring: ahead of 300 is 600 (300 m); ahead of 600 is 5600 (5000 m); ahead of
    # 5600 is 300, round the end of the lap (400 m).
    assert nearest_ahead(1, fronts, True, 5700.0) == (0, 300.0)
    assert nearest_ahead(0, fronts, True, 5700.0) == (2, 5000.0)
    assert nearest_ahead(2, fronts, True, 5700.0) == (1, pytest.approx(400.0))
    # On an open line nobody is ahead of the front-most train.
    assert nearest_ahead(2, fronts, False, 5700.0) is None
    assert nearest_ahead(1, fronts, False, 5700.0) == (0, 300.0)
    assert nearest_ahead(0, [100.0], True, 5700.0) is None


def _stop(name: str, at_s: float) -> StopRecord:
    # Journey times differ between trains (each journey starts when it is engaged): headways
    # are taken on the run's clock.
    return StopRecord(
        name=name,
        planned_arrival_s=0.0,
        arrival_s=at_s - 20.0,
        stop_error_m=0.0,
        odometry_interval_m=1.0,
        at_s=at_s,
    )


def test_headways_follow_the_arrivals_at_each_stop() -> None:
    headways = headways_at_stops(
        [
            ("URV2", [_stop("east", 260.0), _stop("south", 500.0)]),
            ("URV1", [_stop("east", 200.0), _stop("south", 400.0), _stop("north", 720.0)]),
            ("URV3", [_stop("east", 330.0)]),
        ]
    )
    seen = {(h.stop, h.ahead, h.behind): h.headway_s for h in headways}
    assert seen == {
        ("east", "URV1", "URV2"): 60.0,
        ("east", "URV2", "URV3"): 70.0,
        ("south", "URV1", "URV2"): 100.0,
    }


def test_expectations_reach_into_the_fleet_block() -> None:
    fleet = {
        "trains": [
            _summary("URV1", passed=True),
            _summary("URV2", passed=False),
        ],
        "min_distance_m": 52.5,
        "min_distance_at_s": 230.0,
        "min_distance_between": ["URV2", "URV1"],
        "headways": [{"stop": "east", "ahead": "URV1", "behind": "URV2", "headway_s": 60.0}],
        "min_headway_s": 60.0,
    }
    kpis = sample_kpis(fleet=fleet)
    assert kpi_value(kpis, "fleet.min_distance_m") == 52.5
    assert kpi_value(kpis, "fleet.trains.passed") == [True, False]
    assert kpi_value(kpis, "fleet.trains.count") == 2
    assert kpi_value(kpis, "fleet.headways.headway_s") == [60.0]
    with pytest.raises(KeyError, match="no KPI"):
        kpi_value(kpis, "fleet.no_such_field")
    assert "fleet" in kpis.model_dump()
    # A single-train run's kpis.json leaves the block out.
    assert "fleet" not in sample_kpis().model_dump()


def _summary(vehicle_id: str, *, passed: bool) -> dict[str, object]:
    return {
        "vehicle_id": vehicle_id,
        "passed": passed,
        "stops": 3,
        "max_stop_error_m": 0.1,
        "max_arrival_delay_s": 1.0,
        "eoa_stops": 1,
        "held_s": 12.4,
        "max_overspeed_kmh": 0.0,
        "etcs_sb_count": 0,
        "etcs_eb_count": 0,
        "vc_eb_count": 0,
        "failed": [] if passed else ["stops.count == 3"],
    }


@pytest.mark.e2e
@pytest.mark.scenario
def test_two_trains_the_one_behind_is_held_by_its_ma_and_follows(tmp_path: Path) -> None:
    """The library's two-trains-following cut to 270 s: the follower closes up to the EoA
    behind the lead standing at the east platform, stands, and follows it into the platform
    once the RBC has extended its MA; the whole stack of both trains on one trackside."""
    text = (SCENARIOS / "two-trains-following.toml").read_text()
    short = tmp_path / "two-trains.toml"
    short.write_text(re.sub(r"(?m)^duration_s = .*$", "duration_s = 270.0", text, count=1))
    report = tmp_path / "report"
    outcome = run_scenario(load_scenario(str(short)), RunOptions(fast=True, report_dir=report))
    lead, follower = outcome.kpis, outcome.trains["URV2"].kpis
    fleet = lead.fleet
    assert fleet is not None
    assert [train.vehicle_id for train in fleet.trains] == ["URV1", "URV2"]
    # The follower stood for the EoA behind the lead, within the ADF's 10 m of it.
    assert len(follower.eoa_stops) == 1
    assert 0.0 < follower.eoa_stops[0].distance_to_eoa_m <= 10.0
    held = {train.vehicle_id: train.held_s for train in fleet.trains}
    assert held["URV1"] == 0.0
    assert held["URV2"] > 5.0
    # Both served the east platform, the follower after the lead had left it.
    assert [s.name for s in lead.stops][:1] == ["east"]
    assert [s.name for s in follower.stops] == ["east"]
    (headway,) = [h for h in fleet.headways if h.stop == "east"]
    assert (headway.ahead, headway.behind) == ("URV1", "URV2")
    assert headway.headway_s > 30.0  # the lead's dwell at least
    # Held by the MA, not by ETCS's brakes; apart by the margin less the intervals.
    for kpis in (lead, follower):
        assert kpis.etcs_sb_count == kpis.etcs_eb_count == kpis.vc_eb_count == 0
        assert kpis.max_overspeed_kmh == 0.0
        assert kpis.min_eoa_margin_m is not None
        assert kpis.min_eoa_margin_m > 0.0
    assert fleet.min_distance_m is not None
    assert fleet.min_distance_m >= 40.0
    assert fleet.min_distance_between == ["URV2", "URV1"]
    # The run's report and the follower's own.
    written = json.loads((report / "kpis.json").read_text(encoding="utf-8"))
    assert written["fleet"]["trains"][1]["vehicle_id"] == "URV2"
    assert (report / "URV2" / "kpis.json").is_file()
    assert (report / "URV2" / "telemetry.npz").is_file()
    page = (report / "report.html").read_text(encoding="utf-8")
    assert "<h2>Trains</h2>" in page
    assert f"{fleet.min_distance_m:.1f} m" in page


@pytest.mark.e2e
@pytest.mark.scenario
def test_a_train_stalled_by_a_fault_holds_the_one_behind(tmp_path: Path) -> None:
    """The library's train-stalls-ahead cut to 270 s: the lead's ATO-OB fails at 160 s and the
    VC's EB stops it for good; the train behind closes up to the EoA the RBC keeps behind it,
    within the ADF's 10 m, and stands there."""
    text = (SCENARIOS / "train-stalls-ahead.toml").read_text()
    short = tmp_path / "stall.toml"
    short.write_text(re.sub(r"(?m)^duration_s = .*$", "duration_s = 270.0", text, count=1))
    outcome = run_scenario(load_scenario(str(short)), RunOptions(fast=True))
    lead, follower = outcome.kpis, outcome.trains["URV2"].kpis
    assert lead.vc_eb_count == 1
    assert follower.vc_eb_count == follower.etcs_sb_count == follower.etcs_eb_count == 0
    # Its last EoA stop is behind the stalled train, and it still stands there.
    last = follower.eoa_stops[-1]
    assert last.time_s > 200.0
    assert 0.0 < last.distance_to_eoa_m <= 10.0
    fleet = lead.fleet
    assert fleet is not None
    assert fleet.trains[1].held_s > 25.0
    assert fleet.min_distance_m is not None
    assert fleet.min_distance_m >= 40.0
    assert outcome.trains["URV2"].kpis.min_eoa_margin_m is not None
    assert outcome.trains["URV2"].kpis.min_eoa_margin_m > 0.0


@pytest.mark.e2e
@pytest.mark.scenario
def test_the_trackside_delays_a_journey_timed_into_the_train_ahead(tmp_path: Path) -> None:
    """The library's two-trains-planned cut to 300 s: the trackside's planner delays the
    journey of the train behind (stored as its next version and sent) so that it keeps beyond
    the reach of its EoA; it serves the east platform on its delayed time, never held."""
    text = (SCENARIOS / "two-trains-planned.toml").read_text()
    short = tmp_path / "planned.toml"
    short.write_text(re.sub(r"(?m)^duration_s = .*$", "duration_s = 300.0", text, count=1))
    outcome = run_scenario(load_scenario(str(short)), RunOptions(fast=True))
    lead, behind = outcome.kpis, outcome.trains["URV2"].kpis
    (sent,) = [action for action in behind.actions or () if action.action == "send_journey"]
    assert sent.accepted
    assert sent.detail is not None
    found = re.match(r"planned (\d+) s later: URV2 would run .* behind URV1", sent.detail)
    assert found is not None, sent.detail
    delay_s = float(found.group(1))
    assert 0.0 < delay_s <= 600.0
    (lead_sent,) = [action for action in lead.actions or () if action.action == "send_journey"]
    assert lead_sent.detail is None  # the first journey on the line goes as stored
    (east,) = behind.stops
    assert east.planned_arrival_s == pytest.approx(185.0 + delay_s)
    assert abs(east.arrival_error_s) <= 2.0
    assert behind.eoa_stops == []
    fleet = lead.fleet
    assert fleet is not None
    assert [train.held_s for train in fleet.trains] == [0.0, 0.0]
    assert fleet.min_distance_m is not None
    assert fleet.min_distance_m > 150.0
    for kpis in (lead, behind):
        assert kpis.etcs_sb_count == kpis.etcs_eb_count == kpis.vc_eb_count == 0
