"""Plan energy and the offline energy-optimal reference."""

from __future__ import annotations

import numpy as np
import pytest

from onboard.adf.energy import OptimalLeg, optimal_leg, plan_traction_energy_j
from onboard.adf.odp import (
    SPEED_OVERREAD_SHARE,
    InfeasibleLegError,
    LspbSegment,
    OdpLeg,
    OdpPlan,
    plan_legs,
)
from onboard.adf.odp_energy import optimise_leg, plan_energy_legs, replan_from_state
from onboard.etcs.braking import BrakingModel, Limit, Target, TargetKind
from onboard.plant import URV_PARAMETERS
from trackdb import LineBuilder, TemporarySpeedRestriction, TrackMap, load_seed_line

pytestmark = pytest.mark.scenario

CAP_MPS = 40 / 3.6


def test_plan_energy_on_level_track_matches_the_physics() -> None:
    flat = TrackMap(LineBuilder(id="flat", name="Flat").straight(3000.0, speed_kmh=80).build())
    plan = plan_legs(flat, start_chainage_m=0.0, stops=[(2000.0, 240.0, 240.0)], cap_mps=CAP_MPS)
    energy = plan_traction_energy_j(plan, URV_PARAMETERS, step_s=0.05)
    segment = plan.legs[0].segment
    assert isinstance(segment, LspbSegment)  # plan_legs plans LSPB legs
    p = URV_PARAMETERS
    mass = p.mass_kg * (1 + p.rotating_mass_factor)
    v = segment.cruise_speed_mps
    cruise_m = v * (segment.duration_s - 2 * segment.blend_s)
    accel_m = 0.5 * v * segment.blend_s

    def resistance(speed: float) -> float:
        return p.davis_a_n + p.davis_b_n_per_mps * speed + p.davis_c_n_per_mps2 * speed**2

    # Kinetic energy plus resistance while accelerating (at about half speed) and cruising;
    # braking needs no traction.
    expected = 0.5 * mass * v**2 + resistance(v / 2) * accel_m + resistance(v) * cruise_m
    assert energy == pytest.approx(expected, rel=0.02)


def test_the_optimum_beats_the_plain_lspb_and_keeps_the_limits() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    plan = plan_legs(ring, start_chainage_m=200.0, stops=[(1775.0, 300.0, 320.0)], cap_mps=CAP_MPS)
    baseline = plan_traction_energy_j(plan, URV_PARAMETERS)
    best = optimal_leg(
        ring,
        URV_PARAMETERS,
        start_chainage_m=200.0,
        distance_m=1775.0,
        duration_s=300.0,
        cap_mps=CAP_MPS,
    )
    assert best.traction_energy_j < 0.95 * baseline
    assert best.speeds_mps.max() <= CAP_MPS + 1e-6
    assert best.speeds_mps[0] == pytest.approx(0.0, abs=1e-6)
    assert best.speeds_mps[-1] == pytest.approx(0.0, abs=1e-6)
    average = (best.speeds_mps[:-1] + best.speeds_mps[1:]) / 2
    ds = np.diff(best.distances_m)
    assert float(np.sum(ds / average)) == pytest.approx(300.0, rel=1e-6)


def test_the_optimum_passes_a_passing_point_at_its_time() -> None:
    """An interior time constraint: the optimum is at the passing point at its time (the point
    a node of the grid, between nodes 10 m apart), arrives on time, and costs more than the
    optimum free to pass it when it likes, which is earlier than asked here."""
    ring = TrackMap(load_seed_line("bologna-ring"))

    def leg(passing: list[tuple[float, float]]) -> OptimalLeg:
        return optimal_leg(
            ring,
            URV_PARAMETERS,
            start_chainage_m=3400.0,
            distance_m=2850.0,
            duration_s=430.0,
            cap_mps=CAP_MPS,
            passing=passing,
        )

    free = leg([])
    bound = leg([(1403.0, 210.0)])
    average = (bound.speeds_mps[:-1] + bound.speeds_mps[1:]) / 2
    times = np.concatenate([[0.0], np.cumsum(np.diff(bound.distances_m) / average)])
    node = int(np.argmin(np.abs(bound.distances_m - 1403.0)))
    assert bound.distances_m[node] == pytest.approx(1403.0)
    assert times[node] == pytest.approx(210.0, abs=1e-3)
    assert times[-1] == pytest.approx(430.0, abs=1e-3)
    free_average = (free.speeds_mps[:-1] + free.speeds_mps[1:]) / 2
    free_times = np.cumsum(np.diff(free.distances_m) / free_average)
    assert float(np.interp(1403.0, free.distances_m[1:], free_times)) < 205.0
    assert bound.traction_energy_j > 1.005 * free.traction_energy_j


def _never_above(plan: OdpPlan, cap_mps: float) -> None:
    """The reference stays under the MRSP and the cap at every instant of the plan."""
    for t in np.arange(0.0, plan.end_s, 0.25):
        distance, speed = plan.reference(float(t))
        limit = min(plan.track_map.mrsp_mps(plan.chainage_m(distance)), cap_mps)
        assert speed <= limit + 1e-6


def test_energy_minimised_lap_saves_against_lspb_and_nears_the_optimum() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    stops = [(1775.0, 300.0, 320.0), (3200.0, 550.0, 570.0), (6050.0, 1000.0, 1000.0)]
    lspb = plan_legs(ring, start_chainage_m=200.0, stops=stops, cap_mps=CAP_MPS)
    ours, kept_plain = plan_energy_legs(
        ring, URV_PARAMETERS, start_chainage_m=200.0, stops=stops, cap_mps=CAP_MPS
    )
    assert kept_plain == 0  # every leg found its profile, the downhill one too
    energy = plan_traction_energy_j(ours, URV_PARAMETERS)
    assert energy <= 0.90 * plan_traction_energy_j(lspb, URV_PARAMETERS)
    best = sum(
        optimal_leg(
            ring,
            URV_PARAMETERS,
            start_chainage_m=200.0 + leg.start_distance_m,
            distance_m=leg.segment.distance_m,
            duration_s=leg.segment.duration_s,
            cap_mps=CAP_MPS,
        ).traction_energy_j
        for leg in lspb.legs
    )
    assert energy <= 1.05 * best
    # Arrival times and stopping points are kept.
    for (distance, arrival, _), leg in zip(stops, ours.legs, strict=True):
        assert leg.start_s + leg.segment.duration_s == pytest.approx(arrival, abs=0.01)
        assert ours.reference(arrival)[0] == pytest.approx(distance, abs=1e-6)
    _never_above(ours, CAP_MPS)


def test_a_leg_follows_the_speed_sections_inside_it() -> None:
    """80 → 40 → 80 km/h inside one leg: the plan runs faster than the lowest limit where the
    line allows, coasts ahead of the 40 km/h section and brakes into it, and stays within 5 % of
    the optimum."""
    line = TrackMap(
        LineBuilder(id="sections", name="Sections")
        .straight(1500.0, speed_kmh=80)
        .straight(800.0, speed_kmh=40)
        .straight(1700.0, speed_kmh=80)
        .build()
    )
    duration_s, cap_mps = 300.0, 80 / 3.6
    leg = optimise_leg(
        line,
        URV_PARAMETERS,
        start_chainage_m=0.0,
        distance_m=3800.0,
        duration_s=duration_s,
        cap_mps=cap_mps,
    )
    assert leg.duration_s == pytest.approx(duration_s, abs=0.01)
    assert leg.max_speed_mps > 40 / 3.6 + 1.0
    slow = (leg.distances_m >= 1500.0) & (leg.distances_m <= 2300.0)
    assert leg.speeds_mps[slow].max() <= 40 / 3.6 + 1e-6
    # Held there, just under the limit: the plan's margin to the MRSP, and below a drop the
    # share ETCS's speed may read high.
    assert leg.speeds_mps[slow].max() <= (40 * (1 - SPEED_OVERREAD_SHARE) - 0.2) / 3.6 + 1e-6
    assert leg.speeds_mps[slow].min() >= (40 * (1 - SPEED_OVERREAD_SHARE) - 0.2) / 3.6 - 1e-6
    # Coasting: the speed only falls from the end of the acceleration to the section.
    ahead = (leg.distances_m >= 300.0) & (leg.distances_m <= 1500.0)
    assert np.all(np.diff(leg.speeds_mps[ahead]) <= 1e-9)
    assert leg.speeds_mps[ahead][0] - leg.speeds_mps[ahead][-1] > 40 / 3.6 * 0.2
    best = optimal_leg(
        line,
        URV_PARAMETERS,
        start_chainage_m=0.0,
        distance_m=3800.0,
        duration_s=duration_s,
        cap_mps=cap_mps,
    )
    assert leg.traction_energy_j <= 1.05 * best.traction_energy_j
    plan = OdpPlan([OdpLeg(0.0, 0.0, leg)], start_chainage_m=0.0, track_map=line)
    _never_above(plan, cap_mps)
    assert plan_traction_energy_j(plan, URV_PARAMETERS) == pytest.approx(
        leg.traction_energy_j, rel=0.02
    )


def test_a_steep_descent_is_held_by_the_brake_not_exceeded() -> None:
    line = TrackMap(
        LineBuilder(id="descent", name="Descent")
        .straight(600.0, speed_kmh=60)
        .straight(1400.0, speed_kmh=60, gradient_permille=-25.0)
        .straight(500.0, speed_kmh=60)
        .build()
    )
    leg = optimise_leg(
        line,
        URV_PARAMETERS,
        start_chainage_m=0.0,
        distance_m=2400.0,
        duration_s=220.0,
        cap_mps=60 / 3.6,
    )
    assert leg.duration_s == pytest.approx(220.0, abs=0.01)
    assert leg.max_speed_mps <= 60 / 3.6 + 1e-6
    assert leg.speeds_mps[-1] == 0.0


def test_an_impossible_schedule_is_refused() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    with pytest.raises(InfeasibleLegError, match="more than the"):
        optimise_leg(
            ring,
            URV_PARAMETERS,
            start_chainage_m=200.0,
            distance_m=1775.0,
            duration_s=100.0,
            cap_mps=CAP_MPS,
        )


def test_replanning_from_a_moving_train_obeys_a_new_restriction() -> None:
    """A TSR of 20 km/h appears 300 m ahead of a train at 40 km/h: the new plan brakes to it
    before it starts, holds it through it, and stops at the stop."""
    ring = TrackMap(load_seed_line("bologna-ring"))
    ring.add_temporary_speed_restriction(
        TemporarySpeedRestriction(id="tsr-1", start_m=800.0, end_m=1100.0, speed_mps=20 / 3.6)
    )
    plan = replan_from_state(
        ring,
        URV_PARAMETERS,
        now_s=50.0,
        start_chainage_m=200.0,
        distance_m=300.0,
        speed_mps=CAP_MPS,
        stop_distance_m=1275.0,
        cruise_mps=CAP_MPS,
    )
    assert plan.reference(50.0) == pytest.approx((300.0, CAP_MPS))
    _never_above(plan, CAP_MPS)
    assert plan.reference(plan.end_s) == pytest.approx((1575.0, 0.0))
    times = np.arange(50.0, plan.end_s, 0.5)
    in_tsr = [plan.reference(float(t)) for t in times]
    assert max(v for d, v in in_tsr if 600.0 <= d <= 900.0) <= 20 / 3.6 + 1e-6
    assert max(v for d, v in in_tsr if d > 950.0) > 30 / 3.6  # back up after it


def test_a_tsr_inside_the_braking_distance_is_met_by_braking_and_the_plan_goes_on() -> None:
    """A TSR of 20 km/h comes into force 40 m ahead of a train at 40 km/h, closer than the
    planned braking into a limit allows: the new plan brakes at the recovery rate from the
    train's speed, re-enters the envelope, and still stops at the stop (no refusal)."""
    from onboard.adf.odp_energy import RECOVERY_BRAKING_MPS2

    ring = TrackMap(load_seed_line("bologna-ring"))
    ring.add_temporary_speed_restriction(
        TemporarySpeedRestriction(id="tsr-1", start_m=540.0, end_m=800.0, speed_mps=20 / 3.6)
    )
    plan = replan_from_state(
        ring,
        URV_PARAMETERS,
        now_s=50.0,
        start_chainage_m=200.0,
        distance_m=300.0,
        speed_mps=CAP_MPS,
        stop_distance_m=1275.0,
        cruise_mps=CAP_MPS,
    )
    assert plan.reference(50.0) == pytest.approx((300.0, CAP_MPS))
    recovered_m = 300.0 + (CAP_MPS**2 - (20 / 3.6) ** 2) / (2 * RECOVERY_BRAKING_MPS2)
    for t in np.arange(50.0, 90.0, 0.5):
        distance, speed = plan.reference(float(t))
        if distance < recovered_m:
            # Braking at the recovery rate from the train's speed, never slower to react.
            recovery_v2 = CAP_MPS**2 - 2 * RECOVERY_BRAKING_MPS2 * (distance - 300.0)
            assert speed**2 == pytest.approx(recovery_v2, abs=0.2)
        elif distance <= 600.0:
            assert speed <= 20 / 3.6 + 1e-6  # then under the TSR through it
    assert plan.reference(plan.end_s) == pytest.approx((1575.0, 0.0))


def test_a_train_too_fast_to_stop_in_the_leg_is_refused() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    with pytest.raises(InfeasibleLegError, match="within the leg"):
        replan_from_state(
            ring,
            URV_PARAMETERS,
            now_s=50.0,
            start_chainage_m=200.0,
            distance_m=300.0,
            speed_mps=CAP_MPS,
            stop_distance_m=40.0,
            cruise_mps=CAP_MPS,
        )


@pytest.mark.parametrize("gradient_permille", [0.0, -10.0])
def test_braking_into_a_lower_limit_stays_under_the_etcs_permitted_curve(
    gradient_permille: float,
) -> None:
    """80 → 20 km/h inside a leg: braking at the stop's rate met 20 km/h on time but crossed
    the permitted speed ETCS supervises the decrease with (from the max safe front end, 5 m +
    5 % of the distance since the balise group ahead of the estimate)."""
    line = TrackMap(
        LineBuilder(id="drop", name="Drop")
        .balise_group(1, 100.0)
        .straight(1500.0, speed_kmh=80, gradient_permille=gradient_permille)
        .straight(400.0, speed_kmh=20)
        .straight(1000.0, speed_kmh=80)
        .build()
    )
    leg = optimise_leg(
        line,
        URV_PARAMETERS,
        start_chainage_m=0.0,
        distance_m=2800.0,
        duration_s=290.0,
        cap_mps=80 / 3.6,
    )
    assert leg.duration_s == pytest.approx(290.0, abs=0.01)
    decrease = Target(TargetKind.SPEED_DECREASE, 1500.0, 20 / 3.6)
    limits = BrakingModel().target_limits(decrease, track_map=line, from_m=0.0)
    margins = []
    for distance, speed in zip(leg.distances_m.tolist(), leg.speeds_mps.tolist(), strict=True):
        if not 300.0 <= distance < 1500.0:
            continue
        beyond = line.distance_beyond_balise_group_m(distance)
        assert beyond is not None
        front = distance + 5.0 + 0.05 * beyond
        curve = limits.speed_mps(Limit.PERMITTED, 1500.0 - front, acceleration_mps2=0.0)
        permitted = max(curve, decrease.speed_mps)  # the curve ends at the target speed
        margins.append(permitted - speed)
    assert min(margins) >= 0.0
    # ... and the plan still brakes late enough to be worth it: within 2 km/h of the curve.
    assert min(margins) <= 2 / 3.6


def test_the_planners_compiled_loops_are_their_interpreted_twins_bit_for_bit() -> None:
    """The planner's forward run and backward coast are compiled (onboard.runtime.compiled):
    on a real leg's grid, with random speeds, targets and coast flags, the compiled functions
    give the interpreter's bits (``py_func`` is the same source, interpreted)."""
    from onboard.adf.odp_energy import LegTrack, _coast_backwards, _forward
    from onboard.plant.point_mass import MIN_POWER_SPEED_MPS
    from onboard.runtime.compiled import interpreted

    track = LegTrack(
        TrackMap(load_seed_line("bologna-ring")),
        URV_PARAMETERS,
        start_chainage_m=300.0,
        distance_m=4000.0,
    )
    p = URV_PARAMETERS
    davis = (p.davis_a_n, p.davis_b_n_per_mps, p.davis_c_n_per_mps2)
    rng = np.random.default_rng(24)
    n = track.steps
    for _ in range(20):
        targets = rng.uniform(0.0, 14.0, n + 1)
        coasting = np.where(rng.random(n + 1) < 0.3, np.inf, rng.uniform(0.0, 16.0, n + 1))
        envelope = rng.uniform(2.0, 20.0, n + 1)
        coast_only = rng.random(n) < 0.1
        arguments = (
            float(rng.uniform(0.0, 12.0)),
            coasting,
            envelope * envelope,
            targets * targets,
            track.track_forces_n,
            coast_only,
            davis,
            (p.max_traction_force_n, p.max_traction_power_w, MIN_POWER_SPEED_MPS),
            (track.effective_mass_kg, track.step_m, track.max_acceleration_mps2),
        )
        assert np.array_equal(_forward(*arguments), interpreted(_forward)(*arguments))
        curves = [np.full(n + 1, np.inf), np.full(n + 1, np.inf)]
        first = int(rng.integers(0, n))
        start = (float(rng.uniform(0.0, 100.0)), targets * targets, track.track_forces_n)
        _coast_backwards(curves[0], first, *start, davis, 2.0 * track.step_m / 9.0e3)
        interpreted(_coast_backwards)(curves[1], first, *start, davis, 2.0 * track.step_m / 9.0e3)
        assert np.array_equal(curves[0], curves[1])
