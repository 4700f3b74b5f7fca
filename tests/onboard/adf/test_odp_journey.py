"""Energy plans on any leg (issue 22): passing points, descents, 200 km/h, short legs, and no
fallback on the library's journeys."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from deploy.scenario.generate import _journey_start_m
from deploy.scenario.line_source import resolve_line
from deploy.scenario.loader import load_scenario
from onboard.adf.energy import optimal_leg
from onboard.adf.journey import plan_journey
from onboard.adf.odp import InfeasibleLegError, OdpPlan
from onboard.adf.odp_energy import MAX_BRAKING_MPS2, ProfileLeg, optimise_leg
from onboard.adf.odp_journey import (
    EnergyPlan,
    PassingPoint,
    join_profiles,
    plan_energy_journey,
)
from onboard.plant import URV_PARAMETERS, PointMassModel
from onboard.plant.point_mass import PointMassParameters
from onboard.stack import OnboardStack
from protocol import messages as m
from protocol.units import MPS_PER_KMH
from tests.onboard.test_stack import StandingLocator
from trackdb import LineBuilder, TrackMap, load_seed_line
from trackdb.journey import Journey, check_journey, journey_profile_message

pytestmark = pytest.mark.scenario

SCENARIOS = Path(__file__).resolve().parents[3] / "deploy" / "scenarios"
RING_CAP_MPS = 40 * MPS_PER_KMH


def _brake_limited(model: PointMassParameters) -> PointMassParameters:
    """The model with the brake of the plan's service braking: the optimum the plans are judged
    against brakes no harder than they do (docs/energy-planning.md)."""
    effective = model.mass_kg * (1.0 + model.rotating_mass_factor)
    return dataclasses.replace(model, max_brake_force_n=MAX_BRAKING_MPS2 * effective)


def _profile(planned: EnergyPlan, leg: int = 0) -> ProfileLeg:
    segment = planned.plan.legs[leg].segment
    assert isinstance(segment, ProfileLeg)
    return segment


def _ring_profile(points: tuple[m.TimingPoint, ...], track_data_version: str) -> m.JourneyProfile:
    """A journey profile on the ring at the journey cap of these tests."""
    return m.JourneyProfile(
        vehicle_id="URV1",
        journey_id="j",
        version=1,
        status="valid",
        line_id="bologna-ring",
        track_data_version=track_data_version,
        max_speed_mps=RING_CAP_MPS,
        timing_points=points,
    )


def _time_at_m(profile: ProfileLeg, distance_m: float) -> float:
    return float(np.interp(distance_m, profile.distances_m, profile.times_s))


def test_a_passing_point_is_passed_at_its_time_and_the_stop_reached_on_time() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    # South to north (2850 m in 430 s), passing 1400 m in at 190 s: later than the
    # unconstrained plan would (it passes there at about 205 s) asks for a faster first part.
    free = plan_energy_journey(
        ring,
        URV_PARAMETERS,
        start_chainage_m=3400.0,
        stops=[(2850.0, 430.0, 430.0)],
        cap_mps=RING_CAP_MPS,
    )
    assert abs(_time_at_m(_profile(free), 1400.0) - 190.0) > 5.0  # the point constrains
    planned = plan_energy_journey(
        ring,
        URV_PARAMETERS,
        start_chainage_m=3400.0,
        stops=[(2850.0, 430.0, 430.0)],
        passing=[PassingPoint("p", 1400.0, 190.0)],
        cap_mps=RING_CAP_MPS,
    )
    profile = _profile(planned)
    assert planned.kept_plain == 0
    assert not planned.passing_missed
    assert _time_at_m(profile, 1400.0) == pytest.approx(190.0, abs=0.1)
    assert profile.duration_s == pytest.approx(430.0, abs=0.1)
    assert profile.speeds_mps[-1] == pytest.approx(0.0, abs=1e-6)
    assert float(np.interp(1400.0, profile.distances_m, profile.speeds_mps)) > 1.0  # passes
    assert np.all(np.diff(profile.times_s) > 0.0)
    assert profile.max_speed_mps <= RING_CAP_MPS
    # The passing time costs energy against the free plan, never less.
    assert profile.traction_energy_j >= _profile(free).traction_energy_j


def test_a_passing_timing_point_of_a_journey_profile_constrains_its_leg() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    points = (
        m.TimingPoint(
            id="east",
            position_m=1975.0,
            kind="stopping",
            arrival_time_s=300.0,
            departure_time_s=320.0,
        ),
        m.TimingPoint(id="pass", position_m=2600.0, kind="passing", arrival_time_s=400.0),
        m.TimingPoint(
            id="south",
            position_m=3400.0,
            kind="stopping",
            arrival_time_s=550.0,
            end_of_journey=True,
        ),
    )
    profile = _ring_profile(points, "x")
    journey = plan_journey(ring, URV_PARAMETERS, profile, start_chainage_m=200.0)
    assert [s.timing_point_id for s in journey.stops] == ["east", "south"]
    assert [p.timing_point_id for p in journey.passing] == ["pass"]
    assert journey.legs_kept_plain == 0
    assert not journey.passing_missed
    # The reference passes the point (1775 + 625 m from the start) at its time.
    plan: OdpPlan = journey.plan
    times = np.arange(320.0, 550.0, 0.05)
    travelled = np.array([plan.reference(float(t))[0] for t in times])
    assert float(np.interp(2400.0, travelled, times)) == pytest.approx(400.0, abs=0.2)


def test_a_passing_time_no_profile_meets_is_reported_not_a_crash() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    planned = plan_energy_journey(
        ring,
        URV_PARAMETERS,
        start_chainage_m=3400.0,
        stops=[(2850.0, 430.0, 430.0)],
        passing=[PassingPoint("too-early", 1400.0, 30.0)],  # 1.4 km in 30 s at 40 km/h
        cap_mps=RING_CAP_MPS,
    )
    assert [miss.timing_point_id for miss in planned.passing_missed] == ["too-early"]
    assert planned.kept_plain == 0
    assert _profile(planned).duration_s == pytest.approx(430.0, abs=0.1)


def test_a_steep_descent_leg_is_within_one_percent_of_the_optimum() -> None:
    # 25 ‰ down: gravity (0.25 m/s²) beats the resistance, so holding a speed on it brakes;
    # the optimum coasts and lets the speed rise to the limit.
    line = TrackMap(
        LineBuilder(id="valley", name="Valley")
        .straight(1500.0, speed_kmh=80)
        .straight(1500.0, speed_kmh=80, gradient_permille=-25.0)
        .straight(1500.0, speed_kmh=80)
        .build()
    )
    ours = optimise_leg(
        line, URV_PARAMETERS, start_chainage_m=0.0, distance_m=4400.0, duration_s=300.0
    )
    best = optimal_leg(
        line,
        _brake_limited(URV_PARAMETERS),
        start_chainage_m=0.0,
        distance_m=4400.0,
        duration_s=300.0,
    )
    assert ours.duration_s == pytest.approx(300.0, abs=0.05)
    assert ours.traction_energy_j <= 1.01 * best.traction_energy_j
    # On the descent the train runs faster than the speed it holds, up to the limit.
    on_descent = (ours.distances_m > 1600.0) & (ours.distances_m < 3000.0)
    assert ours.speeds_mps[on_descent].max() > ours.holding_speed_mps + 1.0


def test_a_200_kmh_leg_is_within_one_percent_of_the_optimum_under_the_cap() -> None:
    line = TrackMap(load_seed_line("milano-bologna"))
    cap = 200 * MPS_PER_KMH
    planned = plan_energy_journey(
        line,
        URV_PARAMETERS,
        start_chainage_m=128_000.0,
        stops=[(30_000.0, 700.0, 700.0)],
        cap_mps=cap,
    )
    profile = _profile(planned)
    assert planned.kept_plain == 0
    assert profile.duration_s == pytest.approx(700.0, abs=0.05)
    assert profile.max_speed_mps <= cap
    assert profile.max_speed_mps > 180 * MPS_PER_KMH
    best = optimal_leg(
        line,
        _brake_limited(URV_PARAMETERS),
        start_chainage_m=128_000.0,
        distance_m=30_000.0,
        duration_s=700.0,
        cap_mps=cap,
        step_m=50.0,
    )
    assert profile.traction_energy_j <= 1.01 * best.traction_energy_j


def test_a_short_leg_is_planned_on_time() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    planned = plan_energy_journey(
        ring,
        URV_PARAMETERS,
        start_chainage_m=200.0,
        stops=[(120.0, 25.0, 25.0)],
        cap_mps=RING_CAP_MPS,
    )
    assert planned.kept_plain == 0
    assert _profile(planned).duration_s == pytest.approx(25.0, abs=0.05)


def test_a_leg_the_planned_braking_cannot_make_brakes_harder_instead_of_falling_back() -> None:
    # 120 m in 23 s: the plain LSPB (0.91 m/s² both ways) is feasible; braking into the stop
    # at the planned 0.7 m/s² takes at least 24 s: the planner brakes as hard as the LSPB does.
    ring = TrackMap(load_seed_line("bologna-ring"))
    with pytest.raises(InfeasibleLegError):
        optimise_leg(
            ring,
            URV_PARAMETERS,
            start_chainage_m=200.0,
            distance_m=120.0,
            duration_s=23.0,
            cap_mps=RING_CAP_MPS,
        )
    planned = plan_energy_journey(
        ring,
        URV_PARAMETERS,
        start_chainage_m=200.0,
        stops=[(120.0, 23.0, 23.0)],
        cap_mps=RING_CAP_MPS,
    )
    assert planned.kept_plain == 0
    assert not planned.fallbacks
    assert _profile(planned).duration_s == pytest.approx(23.0, abs=0.05)


def test_join_profiles_keeps_time_distance_and_energy() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    first = optimise_leg(
        ring,
        URV_PARAMETERS,
        start_chainage_m=200.0,
        distance_m=500.0,
        duration_s=60.0,
        final_speed_mps=5.0,
    )
    rest = optimise_leg(
        ring,
        URV_PARAMETERS,
        start_chainage_m=700.0,
        distance_m=500.0,
        duration_s=70.0,
        initial_speed_mps=float(first.speeds_mps[-1]),
    )
    joined = join_profiles([first, rest])
    assert joined.distance_m == pytest.approx(1000.0)
    assert joined.duration_s == pytest.approx(first.duration_s + rest.duration_s)
    assert joined.traction_energy_j == pytest.approx(
        first.traction_energy_j + rest.traction_energy_j
    )
    assert joined.at(first.duration_s)[0] == pytest.approx(500.0, abs=1e-6)


def _library_journeys() -> list[Path]:
    return sorted(
        path for path in SCENARIOS.glob("*.toml") if load_scenario(path).journey is not None
    )


@pytest.mark.parametrize("path", _library_journeys(), ids=lambda p: p.stem)
def test_no_leg_of_a_library_journey_falls_back(path: Path) -> None:
    spec = load_scenario(path)
    assert spec.journey is not None
    track_map = TrackMap(resolve_line(spec))
    start = _journey_start_m(track_map, spec.vehicle.start_position_m)
    cap = spec.journey.max_speed_kmh
    journey = Journey(
        id=spec.journey.id,
        line_id=track_map.line.id,
        start_position_m=start,
        max_speed_mps=None if cap is None else cap * MPS_PER_KMH,
        timing_points=spec.journey.timing_points,
    )
    message = journey_profile_message(
        journey,
        check_journey(journey, track_map),
        vehicle_id="URV1",
        version=1,
        track_data_version="x",
    )
    planned = plan_journey(track_map, URV_PARAMETERS, message, start_chainage_m=start)
    assert planned.legs_kept_plain == 0, planned.fallbacks
    assert not planned.fallbacks
    assert not planned.passing_missed


def test_a_leg_the_vehicle_cannot_run_in_time_keeps_the_lspb_with_its_reason() -> None:
    # 13 km over a 12 ‰ hill in 300 s at up to 200 km/h: the LSPB (0.5 m/s² at any speed) is
    # feasible, the URV's 400 kW are not enough: a fallback, counted and explained.
    line = TrackMap(load_seed_line("milano-bologna"))
    planned = plan_energy_journey(
        line,
        URV_PARAMETERS,
        start_chainage_m=45_000.0,
        stops=[(13_000.0, 300.0, 300.0)],
        cap_mps=200 * MPS_PER_KMH,
    )
    assert planned.kept_plain == 1
    assert [fallback.leg for fallback in planned.fallbacks] == [0]
    assert "more than the 300.0 s scheduled" in planned.fallbacks[0].reason
    assert not isinstance(planned.plan.legs[0].segment, ProfileLeg)


def test_a_passing_time_not_kept_is_an_event_of_the_journey_s_acceptance() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    onboard = OnboardStack(
        ring,
        StandingLocator(200.0),
        URV_PARAMETERS,
        PointMassModel(URV_PARAMETERS).force_limits_n,
        start_position_m=200.0,
    )
    onboard.track_database.record_trackside_version(
        m.LineVersionReply(line_id="bologna-ring", version=ring.version)
    )
    points = (
        m.TimingPoint(id="early", position_m=1500.0, kind="passing", arrival_time_s=20.0),
        m.TimingPoint(
            id="east",
            position_m=1975.0,
            kind="stopping",
            arrival_time_s=300.0,
            end_of_journey=True,
        ),
    )
    profile = _ring_profile(points, ring.version)
    assert onboard.review_journey(profile) == (True, None)
    events = onboard.take_events()
    missed = [event for event in events if event.code == "journey.passing_time_missed"]
    assert len(missed) == 1
    assert missed[0].severity is m.EventSeverity.WARNING
    assert "early" in missed[0].text


def test_two_passing_points_in_one_leg_are_both_kept() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    passing = [PassingPoint("p1", 900.0, 125.0), PassingPoint("p2", 2000.0, 290.0)]
    planned = plan_energy_journey(
        ring,
        URV_PARAMETERS,
        start_chainage_m=3400.0,
        stops=[(2850.0, 430.0, 430.0)],
        passing=passing,
        cap_mps=RING_CAP_MPS,
    )
    profile = _profile(planned)
    assert not planned.passing_missed
    assert _time_at_m(profile, 900.0) == pytest.approx(125.0, abs=0.1)
    assert _time_at_m(profile, 2000.0) == pytest.approx(290.0, abs=0.1)
    assert profile.duration_s == pytest.approx(430.0, abs=0.1)
