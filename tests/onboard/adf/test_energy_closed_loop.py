"""Closed loop on the energy plan with the model mismatch of issue 5 (mass +5 %, Davis ±10 %) on
bologna-ring: every stop within 0.5 m and 2 s, and the traction energy the plant drew within
5 % of the offline optimum on the plant's true parameters (issue 22).

The ADF alone on the point-mass plant (``deploy.bench.adf_closed_loop``: ideal sensors, no
ETCS); the whole stack's certificate is ``tests/deploy/test_run_bologna_ring.py``'s.
"""

from __future__ import annotations

import pytest

from deploy.bench.adf_closed_loop import ClosedLoopRecord, Stop, run_autonomous_journey
from onboard.adf.energy import optimal_leg
from onboard.adf.nmpc import NmpcController
from onboard.adf.odp_energy import plan_energy_legs
from onboard.plant import URV_PARAMETERS
from onboard.plant.point_mass import PointMassParameters, with_model_mismatch
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.scenario

START_M = 200.0
CAP_MPS = 40 / 3.6
STOPS = [(1775.0, 300.0, 320.0), (3200.0, 550.0, 570.0), (6050.0, 1000.0, 1000.0)]
TRUTH: PointMassParameters = with_model_mismatch(URV_PARAMETERS)


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line("bologna-ring"))


@pytest.fixture(scope="module")
def record(ring: TrackMap) -> ClosedLoopRecord:
    plan, kept_plain = plan_energy_legs(
        ring, URV_PARAMETERS, start_chainage_m=START_M, stops=STOPS, cap_mps=CAP_MPS
    )
    assert kept_plain == 0
    return run_autonomous_journey(
        plan,
        stops=[Stop(distance, arrival) for distance, arrival, _ in STOPS],
        model=URV_PARAMETERS,
        truth=TRUTH,
        controller=NmpcController(URV_PARAMETERS),
        duration_s=1010.0,
    )


def test_every_stop_within_half_a_metre_and_two_seconds(record: ClosedLoopRecord) -> None:
    assert sorted(record.arrivals) == [0, 1, 2]
    for index, (_, planned_arrival_s, _) in enumerate(STOPS):
        arrival_s, stop_error_m = record.arrivals[index]
        assert abs(stop_error_m) <= 0.5
        assert abs(arrival_s - planned_arrival_s) <= 2.0


def test_the_energy_driven_is_within_five_percent_of_the_true_optimum(
    ring: TrackMap, record: ClosedLoopRecord
) -> None:
    """Each leg's optimum from its departure to its actual arrival, on the truth."""
    optimum_j, depart_m, depart_s = 0.0, 0.0, 0.0
    for index, (distance_m, _, departure_s) in enumerate(STOPS):
        arrival_s, stop_error_m = record.arrivals[index]
        leg = optimal_leg(
            ring,
            TRUTH,
            start_chainage_m=START_M + depart_m,
            distance_m=distance_m + stop_error_m - depart_m,
            duration_s=arrival_s - depart_s,
            cap_mps=CAP_MPS,
        )
        optimum_j += leg.traction_energy_j
        depart_m, depart_s = distance_m + stop_error_m, departure_s
    ratio = record.traction_energy_j / optimum_j
    assert 1.0 <= ratio <= 1.05, ratio
