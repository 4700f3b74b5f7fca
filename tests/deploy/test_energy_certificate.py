"""The energy certificate: legs found in the telemetry, the plan's energy from the reference, the
offline optimum on the plant's truth and the ratios (issue 22)."""

from __future__ import annotations

import numpy as np
import pytest

from deploy.scenario.energy_certificate import (
    JourneyTiming,
    certify,
    driven_legs,
    reference_energy_j,
)
from onboard.adf.energy import OptimalLeg, optimal_leg, plan_traction_energy_j
from onboard.adf.odp import plan_legs
from onboard.plant import URV_PARAMETERS
from onboard.plant.point_mass import PointMassParameters, with_model_mismatch
from protocol.units import J_PER_KWH
from trackdb import TrackMap, load_seed_line

START_M = 200.0
CAP_MPS = 40 / 3.6
LEG_M, LEG_S = 1200.0, 180.0
ORIGIN_S = 10.0
SAMPLE_S = 0.2


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line("bologna-ring"))


def _telemetry(
    ring: TrackMap, *, extra_traction_j: float = 0.0, late_s: float = 0.0
) -> dict[str, np.ndarray]:
    """A run that follows a one-leg LSPB plan exactly (starting ``late_s`` after the journey's
    start, so arriving that late), its traction counter the plan's energy plus
    ``extra_traction_j`` spread over the leg."""
    plan = plan_legs(ring, start_chainage_m=START_M, stops=[(LEG_M, LEG_S, LEG_S)], cap_mps=CAP_MPS)
    times = np.arange(0.0, ORIGIN_S + late_s + LEG_S + 20.0, SAMPLE_S)
    journey = times - ORIGIN_S - late_s
    samples = np.array([plan.reference(float(t)) if t >= 0 else (0.0, 0.0) for t in journey])
    total = plan_traction_energy_j(plan, URV_PARAMETERS) + extra_traction_j
    share = np.clip(samples[:, 0] / LEG_M, 0.0, 1.0)
    reference = np.array([plan.reference(float(t))[1] for t in times - ORIGIN_S])
    return {
        "time_s": times,
        "position_m": START_M + samples[:, 0],
        "speed_mps": samples[:, 1],
        "reference_speed_mps": np.where(times >= ORIGIN_S, reference, np.nan),
        "traction_energy_j": share * total,
    }


def _timing(arrival_s: float = LEG_S) -> JourneyTiming:
    return JourneyTiming(origin_s=ORIGIN_S, origin_m=START_M, stops=[("east", arrival_s)])


def test_a_leg_runs_from_the_standstill_left_to_the_stop_served(ring: TrackMap) -> None:
    columns = _telemetry(ring, late_s=1.0)
    (leg,) = driven_legs(columns, _timing(LEG_S + 1.0))
    assert leg.departure_s == pytest.approx(ORIGIN_S + 1.0, abs=SAMPLE_S + 1e-9)
    assert leg.arrival_s == pytest.approx(ORIGIN_S + LEG_S + 1.0)
    assert leg.distance_m == pytest.approx(LEG_M, abs=0.5)
    assert leg.plan_start_s == ORIGIN_S


def test_the_plan_energy_from_the_reference_is_the_plans(ring: TrackMap) -> None:
    plan = plan_legs(ring, start_chainage_m=START_M, stops=[(LEG_M, LEG_S, LEG_S)], cap_mps=CAP_MPS)
    columns = _telemetry(ring)
    from_reference = reference_energy_j(
        columns, ring, URV_PARAMETERS, start_s=ORIGIN_S, end_s=ORIGIN_S + LEG_S
    )
    assert from_reference == pytest.approx(plan_traction_energy_j(plan, URV_PARAMETERS), rel=0.01)


def test_the_ratio_is_driven_over_the_optimum_on_the_truth(ring: TrackMap) -> None:
    truth = with_model_mismatch(URV_PARAMETERS)
    extra_j = 0.02 * J_PER_KWH
    columns = _telemetry(ring, extra_traction_j=extra_j)
    certificate, profiles = certify(
        columns,
        _timing(),
        track_map=ring,
        model=URV_PARAMETERS,
        truth=truth,
        cap_mps=CAP_MPS,
        regenerated_j=None,
    )
    (leg,) = certificate.legs
    optimum = optimal_leg(
        ring,
        truth,
        start_chainage_m=START_M,
        distance_m=leg.distance_m,
        duration_s=leg.arrival_s - leg.departure_s,
        cap_mps=CAP_MPS,
    )
    assert leg.optimum_kwh == pytest.approx(optimum.traction_energy_j / J_PER_KWH, rel=1e-6)
    assert certificate.driven_vs_optimum == pytest.approx(
        certificate.driven_kwh / optimum.traction_energy_j * J_PER_KWH
    )
    # The LSPB (and the extra) cost more than the optimum; the plan's energy is the LSPB's.
    assert certificate.plan_vs_optimum is not None
    assert certificate.driven_vs_optimum is not None
    assert 1.0 < certificate.plan_vs_optimum < certificate.driven_vs_optimum
    assert certificate.driven_kwh - certificate.plan_kwh == pytest.approx(0.02, rel=0.02)
    assert [p.name for p in profiles] == ["east"]
    assert profiles[0].speeds_mps.max() <= CAP_MPS


def test_the_optimum_on_a_heavier_truth_takes_more(ring: TrackMap) -> None:
    def leg(model: PointMassParameters) -> OptimalLeg:
        return optimal_leg(
            ring,
            model,
            start_chainage_m=START_M,
            distance_m=LEG_M,
            duration_s=LEG_S,
            cap_mps=CAP_MPS,
        )

    nominal = leg(URV_PARAMETERS)
    heavier = leg(with_model_mismatch(URV_PARAMETERS))
    assert heavier.traction_energy_j > nominal.traction_energy_j
    # Run in its time, standstill to standstill, under the cap.
    speeds = heavier.speeds_mps
    assert speeds[0] == pytest.approx(0.0, abs=1e-6)
    assert speeds[-1] == pytest.approx(0.0, abs=1e-6)
    middle = 0.5 * (speeds[1:] + speeds[:-1])
    assert float(np.sum(np.diff(heavier.distances_m) / middle)) == pytest.approx(LEG_S, rel=1e-4)


def test_a_leg_no_optimum_can_run_leaves_the_ratios_null(ring: TrackMap) -> None:
    """The arrival recorded far too early for the limits (a corrupt record): IPOPT finds no
    optimum, and the certificate says so rather than failing the run."""
    columns = _telemetry(ring)
    certificate, profiles = certify(
        columns,
        _timing(arrival_s=LEG_S),
        track_map=ring,
        model=URV_PARAMETERS,
        truth=URV_PARAMETERS,
        cap_mps=1.0,  # 1200 m in 180 s under 1 m/s: impossible
        regenerated_j=None,
    )
    (leg,) = certificate.legs
    assert leg.optimum_kwh is None
    assert leg.driven_vs_optimum is None
    assert certificate.optimum_kwh is None
    assert certificate.driven_vs_optimum is None
    assert profiles == []


def test_no_stop_served_no_leg(ring: TrackMap) -> None:
    columns = _telemetry(ring)
    timing = JourneyTiming(origin_s=ORIGIN_S, origin_m=START_M, stops=[])
    certificate, _ = certify(
        columns,
        timing,
        track_map=ring,
        model=URV_PARAMETERS,
        truth=URV_PARAMETERS,
        cap_mps=CAP_MPS,
        regenerated_j=None,
    )
    assert certificate.legs == []
    assert certificate.optimum_kwh is None
