"""Headways between journeys: nominal runs, conflicts between them, and the least delay."""

from __future__ import annotations

import numpy as np
import pytest

from tests.trackdb.ring_journeys import ring_journey
from trackdb import LineBuilder, TrackMap, load_seed_line
from trackdb.headway import (
    Conflict,
    HeadwayRule,
    PlacedRun,
    PlannedStop,
    delayed_journey,
    earliest_delay,
    first_conflict,
    nominal_run,
    planned_stops,
)
from trackdb.journey import Journey, JourneyTimingPoint, check_journey

RULE = HeadwayRule(margin_m=50.0)
URV_LENGTH_M = 6.0


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line("bologna-ring"))


def _placed(
    ring: TrackMap, vehicle_id: str, journey: Journey, *, started_s: float = 0.0
) -> PlacedRun:
    check = check_journey(journey, ring)
    assert check.valid, check.problems
    run = nominal_run(planned_stops(journey, check.distances_m))
    return PlacedRun(vehicle_id, journey.start_position_m, URV_LENGTH_M, run, started_s=started_s)


# Two URVs past the north platform, 250 m apart, both timed to the east one: the one behind
# arrives while the lead still stands there (the library's two-trains-following).
LEAD = ring_journey(
    "lead", 900.0, [("east", 150.0, 180.0), ("south", 330.0, 350.0), ("north", 640.0, None)]
)
FOLLOWER = ring_journey("follower", 650.0, [("east", 165.0, 200.0), ("south", 380.0, None)])


def test_a_nominal_run_arrives_on_time_and_stands_through_its_dwell() -> None:
    run = nominal_run([PlannedStop(1000.0, 150.0, 180.0), PlannedStop(2000.0, 330.0, 330.0)])
    travelled, speed = run.at(np.array([0.0, 75.0, 150.0, 165.0, 180.0, 330.0, 400.0]))
    assert travelled[2:5] == pytest.approx([1000.0] * 3)
    assert speed[2:5] == pytest.approx([0.0] * 3)
    assert travelled[-2:] == pytest.approx([2000.0, 2000.0])
    assert 0.0 < travelled[1] < 1000.0
    # An LSPB at 0.5 m/s²: 1000 m in 150 s cruises at (75 - √(75² - 2000)) / 2 m/s.
    assert run.speed_mps[:150].max() == pytest.approx((75.0 - np.sqrt(75.0**2 - 2000.0)) / 2.0)
    assert run.end_s == pytest.approx(330.0)


def test_a_leg_too_short_in_time_is_run_as_a_triangle_and_arrives_late() -> None:
    run = nominal_run([PlannedStop(800.0, 20.0, 20.0)])
    # 2·√(800 / 0.5) = 80 s, not the 20 s scheduled.
    assert run.end_s == pytest.approx(80.0)
    assert run.travelled_m[-1] == pytest.approx(800.0)
    assert run.speed_mps.max() == pytest.approx(20.0, abs=0.5)


def test_the_train_behind_timed_into_the_lead_conflicts(ring: TrackMap) -> None:
    lead = _placed(ring, "URV1", LEAD)
    follower = _placed(ring, "URV2", FOLLOWER)
    conflict = first_conflict(follower, [lead], RULE, ring_length_m=ring.length_m)
    assert conflict is not None
    assert (conflict.behind, conflict.ahead) == ("URV2", "URV1")
    assert conflict.gap_m < conflict.required_m
    assert 0.0 <= conflict.at_s < 165.0
    assert "URV2 would run" in str(conflict)


def test_the_least_delay_clears_the_conflict_and_one_step_less_does_not(ring: TrackMap) -> None:
    lead = _placed(ring, "URV1", LEAD)

    def follower(delay_s: float) -> PlacedRun:
        return _placed(ring, "URV2", delayed_journey(FOLLOWER, delay_s))

    delay, undelayed = earliest_delay(
        follower, [lead], RULE, ring_length_m=ring.length_m, max_delay_s=600.0, step_s=5.0
    )
    assert undelayed is not None
    assert delay is not None
    assert delay > 0.0
    assert first_conflict(follower(delay), [lead], RULE, ring_length_m=ring.length_m) is None
    earlier = first_conflict(follower(delay - 5.0), [lead], RULE, ring_length_m=ring.length_m)
    assert earlier is not None


def test_a_journey_under_way_is_placed_by_the_time_it_has_run(ring: TrackMap) -> None:
    # The lead accepted its journey 200 s ago: it has left the east platform; a follower
    # from 650 m timed to the east platform now keeps clear of it.
    lead = _placed(ring, "URV1", LEAD, started_s=-200.0)
    follower = _placed(ring, "URV2", FOLLOWER)
    assert first_conflict(follower, [lead], RULE, ring_length_m=ring.length_m) is None


def test_a_train_standing_in_the_way_conflicts_at_any_delay(ring: TrackMap) -> None:
    standing = PlacedRun("URV9", 1500.0, URV_LENGTH_M)

    def lead(delay_s: float) -> PlacedRun:
        return _placed(ring, "URV1", delayed_journey(LEAD, delay_s))

    delay, conflict = earliest_delay(
        lead, [standing], RULE, ring_length_m=ring.length_m, max_delay_s=60.0, step_s=20.0
    )
    assert delay is None
    assert isinstance(conflict, Conflict)
    assert conflict.ahead == "URV9"


def test_on_a_ring_the_gap_is_taken_round_the_lap(ring: TrackMap) -> None:
    # A train standing 100 m past the start of the lap is ahead of one running over the lap's
    # end towards the north platform.
    standing = PlacedRun("URV9", 100.0, URV_LENGTH_M)
    over_the_end = ring_journey("over", 5000.0, [("north", 200.0, None)])
    clear = first_conflict(
        _placed(ring, "URV1", over_the_end), [standing], RULE, ring_length_m=ring.length_m
    )
    assert clear is not None
    assert clear.ahead == "URV9"
    # Standing at 1500 m instead, it is out of the way.
    far = PlacedRun("URV9", 1500.0, URV_LENGTH_M)
    assert (
        first_conflict(
            _placed(ring, "URV1", over_the_end), [far], RULE, ring_length_m=ring.length_m
        )
        is None
    )


def test_on_a_line_only_the_train_behind_at_the_start_can_catch_up() -> None:
    builder = LineBuilder(id="straight", name="Straight")
    builder.straight(6000.0, speed_kmh=60.0)
    builder.stopping_point("a", "A", 2000.0)
    builder.stopping_point("b", "B", 5000.0)
    line = TrackMap(builder.build(geodetic_step_m=100.0))
    ahead = Journey(
        id="ahead",
        line_id="straight",
        start_position_m=1000.0,
        timing_points=(
            JourneyTimingPoint(
                id="b", stopping_point_id="b", arrival_time_s=400.0, end_of_journey=True
            ),
        ),
    )
    behind = Journey(
        id="behind",
        line_id="straight",
        start_position_m=500.0,
        timing_points=(
            JourneyTimingPoint(
                id="a", stopping_point_id="a", arrival_time_s=120.0, end_of_journey=True
            ),
        ),
    )
    runs = [_placed(line, "A", ahead), _placed(line, "B", behind)]
    conflict = first_conflict(runs[1], [runs[0]], RULE, ring_length_m=None)
    assert conflict is not None
    assert (conflict.behind, conflict.ahead) == ("B", "A")
    # Timed to arrive late enough, the train behind stays behind.
    slow = _placed(line, "B", delayed_journey(behind, 300.0))
    assert first_conflict(slow, [runs[0]], RULE, ring_length_m=None) is None


def test_a_delayed_journey_keeps_its_running_times() -> None:
    delayed = delayed_journey(LEAD, 30.0)
    assert [p.arrival_time_s for p in delayed.timing_points] == [180.0, 360.0, 670.0]
    assert [p.departure_time_s for p in delayed.timing_points] == [210.0, 380.0, None]
    assert delayed.id == LEAD.id


def test_on_a_ring_a_train_closing_past_the_one_ahead_within_the_buffer_conflicts(
    ring: TrackMap,
) -> None:
    """150 m behind a standing train and timed to pass it within the buffer time: the gap
    goes below 0 and is a conflict, not a lap."""
    standing = PlacedRun("URV9", 1500.0, URV_LENGTH_M)
    through = ring_journey("through", 1350.0, [("east", 80.0, None)])
    conflict = first_conflict(
        _placed(ring, "URV1", through), [standing], RULE, ring_length_m=ring.length_m
    )
    assert conflict is not None
    assert conflict.ahead == "URV9"
    assert conflict.gap_m < 0.0
