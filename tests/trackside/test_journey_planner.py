"""The trackside's journey planner: journeys planned against the booked journeys of the other
trains on their line, each placed by its own train's clock."""

from __future__ import annotations

import pytest

from tests.trackdb.ring_journeys import RING, ring_journey
from tests.trackside.reports import status_report
from trackdb import TrackMap, load_seed_line
from trackdb.headway import HeadwayRule, PlanningMode
from trackdb.journey import check_journey
from trackside.bridge import VehicleSnapshot
from trackside.journey_planner import JourneyConflictError, JourneyPlanner
from trackside.metrics import planner_metrics

LINE = RING


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line(LINE))


class Fleet:
    """The trains' latest reports, as the bridge's snapshots give them."""

    def __init__(self) -> None:
        self.reports: dict[str, tuple[float, float, str | None]] = {}

    def report(
        self, vehicle_id: str, position_m: float, sim_time_s: float, journey: str | None
    ) -> None:
        self.reports[vehicle_id] = (position_m, sim_time_s, journey)

    def snapshots(self) -> list[VehicleSnapshot]:
        snapshots = []
        for vehicle_id, (position_m, sim_time_s, journey) in self.reports.items():
            status = status_report(vehicle_id, position_m, line_id=LINE).model_copy(
                update={"sim_time_s": sim_time_s, "journey_id": journey}
            )
            snapshots.append(VehicleSnapshot(vehicle_id, True, status, 0.1, True))
        return snapshots


def _planner(
    fleet: Fleet, ring: TrackMap, mode: PlanningMode = PlanningMode.ADJUST
) -> JourneyPlanner:
    return JourneyPlanner(
        HeadwayRule(margin_m=50.0),
        mode=mode,
        fleet=fleet.snapshots,
        lengths=lambda _vehicle: 6.0,
        ring_length_m=lambda line: ring.length_m if line == LINE else None,
        max_delay_s=600.0,
    )


# two-trains-planned's: the lead goes round to the north platform, the train behind 600 m
# back is timed to reach the east platform 5 s after the lead has left it.
LEAD = ring_journey(
    "lead", 900.0, [("east", 150.0, 180.0), ("south", 330.0, 350.0), ("north", 640.0, None)]
)
BEHIND = ring_journey("behind", 300.0, [("east", 185.0, 215.0), ("south", 400.0, None)])


def _lead_booked(
    ring: TrackMap, mode: PlanningMode = PlanningMode.ADJUST, *, lead_clock_s: float = 40.0
) -> tuple[Fleet, JourneyPlanner]:
    """URV1 accepted LEAD at ``lead_clock_s`` on its clock, URV2 stands 600 m behind it."""
    fleet = Fleet()
    fleet.report("URV1", 900.0, lead_clock_s, None)
    fleet.report("URV2", 300.0, 40.0, None)
    planner = _planner(fleet, ring, mode)
    planner.book("URV1", LEAD, check_journey(LEAD, ring))
    fleet.report("URV1", 900.0, lead_clock_s + 1.0, "lead")
    return fleet, planner


def test_a_journey_alone_on_its_line_goes_as_stored(ring: TrackMap) -> None:
    fleet = Fleet()
    fleet.report("URV1", 900.0, 40.0, None)
    fleet.report("URV2", 300.0, 40.0, None)
    planned = _planner(fleet, ring).plan("URV1", LEAD, check_journey(LEAD, ring))
    assert planned.delay_s == 0.0
    assert planned.conflict is None
    assert planned.journey == LEAD


def test_a_journey_timed_into_a_booked_one_is_delayed_until_it_clears(ring: TrackMap) -> None:
    _fleet, planner = _lead_booked(ring)
    planned = planner.plan("URV2", BEHIND, check_journey(BEHIND, ring))
    assert planned.delay_s > 0.0
    assert planned.delay_s % planner.step_s == 0.0
    assert planned.conflict is not None
    assert (planned.conflict.behind, planned.conflict.ahead) == ("URV2", "URV1")
    east = planned.journey.timing_points[0]
    assert east.arrival_time_s == BEHIND.timing_points[0].arrival_time_s + planned.delay_s


def test_the_other_train_is_placed_by_its_own_clock(ring: TrackMap) -> None:
    """Its clock reads 1000 s more than this train's: only the time since it accepted counts.
    Once the lead has run its journey 250 s, the same journey behind it clears."""
    fleet, planner = _lead_booked(ring, lead_clock_s=1040.0)
    delayed = planner.plan("URV2", BEHIND, check_journey(BEHIND, ring)).delay_s
    assert delayed > 0.0
    fleet.report("URV1", 3000.0, 1290.0, "lead")
    assert planner.plan("URV2", BEHIND, check_journey(BEHIND, ring)).delay_s < delayed


def test_a_train_no_longer_on_its_booked_journey_is_not_planned_against(ring: TrackMap) -> None:
    fleet, planner = _lead_booked(ring)
    fleet.report("URV1", 900.0, 50.0, "another")
    assert planner.plan("URV2", BEHIND, check_journey(BEHIND, ring)).delay_s == 0.0


def test_check_mode_refuses_a_conflicting_journey_and_names_the_conflict(ring: TrackMap) -> None:
    _fleet, planner = _lead_booked(ring, PlanningMode.CHECK)
    with pytest.raises(JourneyConflictError, match="URV2 would run .* behind URV1"):
        planner.plan("URV2", BEHIND, check_journey(BEHIND, ring))


def test_no_delay_within_the_longest_clears_a_journey_and_it_is_refused(ring: TrackMap) -> None:
    _fleet, planner = _lead_booked(ring)
    planner.max_delay_s = 10.0
    with pytest.raises(JourneyConflictError, match="even 10 s later"):
        planner.plan("URV2", BEHIND, check_journey(BEHIND, ring))


def test_off_mode_sends_every_journey_as_stored(ring: TrackMap) -> None:
    _fleet, planner = _lead_booked(ring, PlanningMode.OFF)
    assert planner.plan("URV2", BEHIND, check_journey(BEHIND, ring)).journey == BEHIND


def test_the_outcomes_are_counted_for_the_metrics(ring: TrackMap) -> None:
    _fleet, planner = _lead_booked(ring)
    delayed = planner.plan("URV2", BEHIND, check_journey(BEHIND, ring)).delay_s
    planner.plan("URV1", LEAD, check_journey(LEAD, ring))
    planner.max_delay_s = 10.0
    with pytest.raises(JourneyConflictError):
        planner.plan("URV2", BEHIND, check_journey(BEHIND, ring))
    stats = planner.stats
    assert (stats.as_stored, stats.delayed, stats.refused) == (1, 1, 1)
    assert stats.delay_s == delayed
    samples = {
        (sample.name, sample.labels.get("outcome")): sample.value
        for family in planner_metrics(stats)
        for sample in family.samples
    }
    assert samples[("ato_ts_journeys_planned_total", "delayed")] == 1.0
    assert samples[("ato_ts_journeys_planned_total", "refused")] == 1.0
    assert samples[("ato_ts_journey_delay_seconds_total", None)] == delayed
