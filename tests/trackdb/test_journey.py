"""Journeys: validation against the line, leg feasibility, and the profile sent on board."""

from __future__ import annotations

import math

import pytest

from protocol import messages as m
from trackdb import LineBuilder, TrackMap, load_seed_line
from trackdb.journey import (
    URV_LIMITS,
    Journey,
    JourneyTimingPoint,
    VehicleLimits,
    check_journey,
    journey_profile_message,
    minimum_running_times,
)

CAP_40_KMH = 40 / 3.6


def _tp(identifier: str, arrival_s: float, **kwargs: object) -> JourneyTimingPoint:
    if "position_m" not in kwargs:
        kwargs.setdefault("stopping_point_id", identifier)
    return JourneyTimingPoint(id=identifier, arrival_time_s=arrival_s, **kwargs)


def _ring_journey(east_arrival_s: float = 300.0) -> Journey:
    return Journey(
        id="field-test-lap",
        line_id="bologna-ring",
        start_position_m=200.0,
        max_speed_mps=CAP_40_KMH,
        timing_points=(
            _tp("east", east_arrival_s, minimum_dwell_s=20.0),
            _tp("south", east_arrival_s + 250.0, minimum_dwell_s=20.0),
            _tp("north", east_arrival_s + 700.0, end_of_journey=True),
        ),
    )


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line("bologna-ring"))


def test_field_test_lap_with_three_stops_and_a_40_kmh_cap_validates(ring: TrackMap) -> None:
    check = check_journey(_ring_journey(), ring)
    assert check.valid, check.problems
    assert [leg.to_id for leg in check.legs] == ["east", "south", "north"]
    # The lap wraps: north (550 m) is reached after the south platform, a lap later.
    assert check.distances_m[-1] == pytest.approx(5700.0 - 200.0 + 550.0)
    first = check.legs[0]
    assert first.distance_m == pytest.approx(1975.0 - 200.0)
    assert first.minimum_s > first.distance_m / CAP_40_KMH


def test_an_impossible_leg_is_named_with_its_shortfall(ring: TrackMap) -> None:
    check = check_journey(_ring_journey(east_arrival_s=60.0), ring)
    assert not check.valid
    leg = check.legs[0]
    assert leg.shortfall_s == pytest.approx(leg.minimum_s - 60.0)
    assert len(check.problems) == 1
    problem = check.problems[0]
    assert "leg 0 (start → east" in problem
    assert f"by {leg.shortfall_s:.1f} s" in problem


def test_minimum_running_time_matches_the_closed_form() -> None:
    """Flat straight, force-limited acceleration, cap, service braking: t = D/v + v/2a + v/2b."""
    track = TrackMap(LineBuilder(id="flat", name="Flat").straight(3000.0, speed_kmh=72).build())
    vehicle = VehicleLimits(
        mass_kg=10_000.0,
        rotating_mass_factor=0.0,
        max_traction_force_n=5_000.0,
        max_traction_power_w=1e9,
        service_deceleration_mps2=0.5,
        max_speed_mps=100.0,
    )
    (minimum,) = minimum_running_times(track, vehicle, 0.0, [2000.0], [True], step_m=0.5)
    v, a, b = 20.0, 0.5, 0.5
    expected = 2000.0 / v + v / (2 * a) + v / (2 * b)
    assert minimum == pytest.approx(expected, rel=2e-3)


def test_an_uphill_leg_takes_longer() -> None:
    def leg_time(gradient: float) -> float:
        builder = LineBuilder(id="hill", name="Hill").straight(
            3000.0, speed_kmh=120, gradient_permille=gradient
        )
        track = TrackMap(builder.build())
        return minimum_running_times(track, URV_LIMITS, 0.0, [2500.0], [True])[0]

    assert leg_time(15.0) > leg_time(0.0) > leg_time(-15.0)


def test_passing_points_are_not_stops(ring: TrackMap) -> None:
    stops = minimum_running_times(ring, URV_LIMITS, 0.0, [1000.0, 2000.0], [True, True])
    passing = minimum_running_times(ring, URV_LIMITS, 0.0, [1000.0, 2000.0], [False, True])
    assert sum(passing) < sum(stops)


@pytest.mark.parametrize(
    ("points", "problem"),
    [
        (
            (_tp("east", 300.0), _tp("nowhere", 600.0, end_of_journey=True)),
            "unknown stopping point",
        ),
        ((_tp("east", 300.0, end_of_journey=True), _tp("south", 600.0)), "end of journey"),
        (
            (_tp("east", 300.0, end_of_journey=True), _tp("south", 600.0, end_of_journey=True)),
            "end of journey",
        ),
        (
            (
                _tp("east", 300.0),
                _tp(
                    "x",
                    600.0,
                    position_m=3000.0,
                    kind=m.TimingPointKind.PASSING,
                    end_of_journey=True,
                ),
            ),
            "must be a stopping point",
        ),
        (
            (_tp("east", 300.0), _tp("far", 600.0, position_m=9000.0, end_of_journey=True)),
            "beyond the line",
        ),
        ((_tp("east", 300.0), _tp("east", 900.0, end_of_journey=True)), None),
    ],
)
def test_journey_problems(
    ring: TrackMap, points: tuple[JourneyTimingPoint, ...], problem: str | None
) -> None:
    journey = Journey(id="j", line_id="bologna-ring", start_position_m=200.0, timing_points=points)
    check = check_journey(journey, ring)
    if problem is None:  # the same platform twice on a ring: one more lap
        assert check.valid, check.problems
        assert check.distances_m[1] - check.distances_m[0] == pytest.approx(5700.0)
    else:
        assert any(problem in text for text in check.problems), check.problems


def test_points_must_follow_the_direction_of_travel_on_an_open_line() -> None:
    track = TrackMap(LineBuilder(id="open", name="Open").straight(5000.0, speed_kmh=80).build())
    journey = Journey(
        id="j",
        line_id="open",
        start_position_m=1000.0,
        timing_points=(
            _tp("a", 300.0, position_m=3000.0),
            _tp("b", 900.0, position_m=2000.0, end_of_journey=True),
        ),
    )
    check = check_journey(journey, track)
    assert any("not ahead" in text and "b" in text for text in check.problems)


def test_wrong_line_and_bad_start(ring: TrackMap) -> None:
    journey = Journey(
        id="j",
        line_id="milano-bologna",
        start_position_m=99_000.0,
        timing_points=(_tp("east", 300.0, end_of_journey=True),),
    )
    problems = check_journey(journey, ring).problems
    assert any("not 'bologna-ring'" in p for p in problems)
    assert any("start" in p for p in problems)


def test_timing_point_needs_exactly_one_location() -> None:
    with pytest.raises(ValueError, match="either stopping_point_id or position_m"):
        JourneyTimingPoint(id="x", arrival_time_s=1.0)
    with pytest.raises(ValueError, match="either stopping_point_id or position_m"):
        JourneyTimingPoint(id="x", arrival_time_s=1.0, stopping_point_id="x", position_m=3.0)
    with pytest.raises(ValueError, match="departure before arrival"):
        JourneyTimingPoint(id="x", arrival_time_s=10.0, departure_time_s=5.0, position_m=3.0)


def test_the_journey_profile_message(ring: TrackMap) -> None:
    journey = _ring_journey()
    check = check_journey(journey, ring)
    message = journey_profile_message(
        journey, check, vehicle_id="URV1", version=3, track_data_version=ring.version
    )
    assert message.timing_points[-1].end_of_journey
    assert [tp.position_m for tp in message.timing_points] == [1975.0, 3400.0, 550.0]
    assert message.max_speed_mps == pytest.approx(CAP_40_KMH)
    assert m.JourneyProfile.model_validate_json(message.model_dump_json()) == message
    with pytest.raises(ValueError, match="only a valid journey"):
        journey_profile_message(
            journey,
            check_journey(_ring_journey(60.0), ring),
            vehicle_id="URV1",
            version=1,
            track_data_version="x",
        )


def test_milano_bologna_journey_is_computed_quickly_enough_to_validate() -> None:
    track = TrackMap(load_seed_line("milano-bologna"))
    journey = Journey(
        id="mission",
        line_id="milano-bologna",
        start_position_m=500.0,
        timing_points=(
            _tp("reggio-emilia", 3600.0, minimum_dwell_s=60.0),
            _tp("bologna-centrale", 5400.0, end_of_journey=True),
        ),
    )
    check = check_journey(journey, track)
    assert check.valid, check.problems
    assert math.isfinite(check.legs[0].minimum_s)
    # 127.5 km at no more than 200 km/h (the URV's top speed) takes at least 38 min.
    assert check.legs[0].minimum_s > 127_500.0 / (200 / 3.6)
