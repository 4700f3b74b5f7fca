"""The LSPB optimal driving profile: segment formulas, limits, and a plan for the field test."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from onboard.adf.odp import InfeasibleLegError, lspb_segment, plan_legs
from trackdb import TrackMap, load_seed_line

CAP_40_KMH = 40 / 3.6


@given(
    distance=st.floats(min_value=50.0, max_value=5_000.0),
    slack=st.floats(min_value=1.05, max_value=3.0),
)
def test_segment_covers_its_distance_in_its_time(distance: float, slack: float) -> None:
    limit = 30.0
    duration = slack * (distance / limit + limit / 1.0)  # comfortably feasible
    segment = lspb_segment(distance, duration, speed_limit_mps=limit)
    end_distance, end_speed = segment.at(duration)
    assert end_distance == pytest.approx(distance, abs=1e-6)
    assert end_speed == pytest.approx(0.0, abs=1e-9)
    assert segment.cruise_speed_mps <= limit + 1e-9
    times = np.linspace(0.0, duration, 400)
    samples = np.array([segment.at(t) for t in times])
    assert np.all(np.diff(samples[:, 0]) >= -1e-9)  # never goes back
    speeds_from_positions = np.gradient(samples[:, 0], times)
    assert np.max(np.abs(speeds_from_positions - samples[:, 1])) < 0.05 * limit + 0.1


def test_closed_form_values() -> None:
    # Δ = a t_b (T − t_b): 1000 m in 120 s at 0.5 m/s² gives t_b = (120 − √(14400 − 8000))/2.
    segment = lspb_segment(1000.0, 120.0, speed_limit_mps=30.0)
    blend = (120.0 - (120.0**2 - 4 * 1000.0 / 0.5) ** 0.5) / 2
    assert segment.blend_s == pytest.approx(blend)
    assert segment.cruise_speed_mps == pytest.approx(0.5 * blend)


def test_speed_limit_shortens_the_blends() -> None:
    segment = lspb_segment(1000.0, 110.0, speed_limit_mps=10.0)
    assert segment.cruise_speed_mps == pytest.approx(10.0)
    assert segment.blend_s == pytest.approx(110.0 - 1000.0 / 10.0)
    assert segment.acceleration_mps2 == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("distance", "duration", "limit"),
    [(1000.0, 99.0, 10.0), (1000.0, 40.0, 50.0), (0.0, 10.0, 10.0), (1000.0, 105.0, 10.0)],
)
def test_infeasible_segments(distance: float, duration: float, limit: float) -> None:
    with pytest.raises(InfeasibleLegError):
        lspb_segment(distance, duration, speed_limit_mps=limit)


def test_field_test_plan_on_the_ring() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    start = 200.0
    stops = [
        (1775.0, 300.0, 320.0),  # east
        (3200.0, 550.0, 570.0),  # south
        (6050.0, 1000.0, 1000.0),  # north, a lap later
    ]
    plan = plan_legs(ring, start_chainage_m=start, stops=stops, cap_mps=CAP_40_KMH)
    times = np.arange(0.0, plan.end_s + 0.05, 0.1)
    reference = np.array([plan.reference(t) for t in times])
    assert reference[:, 1].max() <= CAP_40_KMH + 1e-9
    for distance, arrival, departure in stops:
        position, speed = plan.reference(arrival)
        assert position == pytest.approx(distance, abs=1e-6)
        assert speed == pytest.approx(0.0, abs=1e-9)
        assert plan.reference(0.5 * (arrival + departure)) == pytest.approx((distance, 0.0))
    assert plan.chainage_m(6050.0) == pytest.approx(550.0)
    for distance, speed in reference[::10]:
        assert speed <= ring.mrsp_mps(plan.chainage_m(distance)) + 1e-9


def test_an_impossible_leg_names_itself() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    with pytest.raises(InfeasibleLegError, match="leg 1"):
        plan_legs(
            ring,
            start_chainage_m=200.0,
            stops=[(1775.0, 300.0, 320.0), (3200.0, 340.0, 360.0)],
            cap_mps=CAP_40_KMH,
        )
