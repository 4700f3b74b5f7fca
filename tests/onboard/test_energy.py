"""Plan energy and the offline energy-optimal reference."""

from __future__ import annotations

import numpy as np
import pytest

from onboard.adf.energy import optimal_leg, plan_traction_energy_j
from onboard.adf.odp import plan_legs
from onboard.plant import URV_PARAMETERS
from trackdb import LineBuilder, TrackMap, load_seed_line

CAP_MPS = 40 / 3.6


def test_plan_energy_on_level_track_matches_the_physics() -> None:
    flat = TrackMap(LineBuilder(id="flat", name="Flat").straight(3000.0, speed_kmh=80).build())
    plan = plan_legs(flat, start_chainage_m=0.0, stops=[(2000.0, 240.0, 240.0)], cap_mps=CAP_MPS)
    energy = plan_traction_energy_j(plan, URV_PARAMETERS, step_s=0.05)
    segment = plan.legs[0].segment
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
        ring, URV_PARAMETERS, start_chainage_m=200.0, distance_m=1775.0, duration_s=300.0,
        cap_mps=CAP_MPS,
    )  # fmt: skip
    assert best.traction_energy_j < 0.95 * baseline
    assert best.speeds_mps.max() <= CAP_MPS + 1e-6
    assert best.speeds_mps[0] == pytest.approx(0.0, abs=1e-6)
    assert best.speeds_mps[-1] == pytest.approx(0.0, abs=1e-6)
    average = (best.speeds_mps[:-1] + best.speeds_mps[1:]) / 2
    ds = np.diff(best.distances_m)
    assert float(np.sum(ds / average)) == pytest.approx(300.0, rel=1e-6)


def test_energy_minimised_plan_saves_against_lspb_and_nears_the_optimum() -> None:
    from onboard.adf.odp_energy import plan_energy_legs

    ring = TrackMap(load_seed_line("bologna-ring"))
    stops = [(1775.0, 300.0, 320.0), (3200.0, 550.0, 570.0), (6050.0, 1000.0, 1000.0)]
    lspb = plan_legs(ring, start_chainage_m=200.0, stops=stops, cap_mps=CAP_MPS)
    ours, kept_plain = plan_energy_legs(
        ring, URV_PARAMETERS, start_chainage_m=200.0, stops=stops, cap_mps=CAP_MPS
    )
    assert kept_plain <= 1
    baseline = plan_traction_energy_j(lspb, URV_PARAMETERS)
    energy = plan_traction_energy_j(ours, URV_PARAMETERS)
    assert energy <= 0.90 * baseline  # at least 10 % less than the plain LSPB
    # Arrival times are kept, and the reference never exceeds the cap.
    for (distance, arrival, _), leg in zip(stops, ours.legs, strict=True):
        assert leg.start_s + leg.segment.duration_s == pytest.approx(arrival, abs=0.2)
        assert ours.reference(arrival)[0] == pytest.approx(distance, abs=0.05)
    times = np.arange(0.0, ours.end_s, 0.5)
    assert max(ours.reference(float(t))[1] for t in times) <= CAP_MPS + 1e-6
    # The first leg (a coasting profile) is within 5 % of the offline optimum.
    best = optimal_leg(
        ring, URV_PARAMETERS, start_chainage_m=200.0, distance_m=1775.0, duration_s=300.0,
        cap_mps=CAP_MPS,
    )  # fmt: skip
    first = plan_legs(ring, start_chainage_m=200.0, stops=stops[:1], cap_mps=CAP_MPS)
    first_ours, _ = plan_energy_legs(
        ring, URV_PARAMETERS, start_chainage_m=200.0, stops=stops[:1], cap_mps=CAP_MPS
    )
    assert plan_traction_energy_j(first_ours, URV_PARAMETERS) <= 1.05 * best.traction_energy_j
    assert plan_traction_energy_j(first, URV_PARAMETERS) > best.traction_energy_j
