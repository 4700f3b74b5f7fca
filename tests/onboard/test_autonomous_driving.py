"""AD in closed loop: ODP + NMPC on the point-mass plant with model mismatch, on bologna-ring.

The seed 000 field-test journey: a lap with three stops under a 40 km/h cap, driven on the plain
LSPB plan and on the energy-minimised plan (which coasts, so leaves the controller less margin).
"""

from __future__ import annotations

import numpy as np
import pytest

from deploy.bench.adf_closed_loop import ClosedLoopRecord, Stop, run_autonomous_journey
from onboard.adf.nmpc import NmpcController
from onboard.adf.odp import plan_legs
from onboard.adf.odp_energy import plan_energy_legs
from onboard.plant import URV_PARAMETERS
from onboard.plant.point_mass import with_model_mismatch
from trackdb import TrackMap, load_seed_line

START_M = 200.0
CAP_MPS = 40 / 3.6
STOPS = [(1775.0, 300.0, 320.0), (3200.0, 550.0, 570.0), (6050.0, 1000.0, 1000.0)]


def mismatched_urv() -> object:
    """The truth differs from the controller's model: mass +5 %, Davis ±10 %."""
    return with_model_mismatch(URV_PARAMETERS)


@pytest.fixture(scope="module", params=["lspb", "energy"])
def record(request: pytest.FixtureRequest) -> ClosedLoopRecord:
    ring = TrackMap(load_seed_line("bologna-ring"))
    if request.param == "lspb":
        plan = plan_legs(ring, start_chainage_m=START_M, stops=STOPS, cap_mps=CAP_MPS)
    else:
        plan, kept_plain = plan_energy_legs(
            ring, URV_PARAMETERS, start_chainage_m=START_M, stops=STOPS, cap_mps=CAP_MPS
        )
        assert kept_plain == 0
    return run_autonomous_journey(
        plan, stops=[Stop(distance, arrival) for distance, arrival, _ in STOPS],
        model=URV_PARAMETERS, truth=mismatched_urv(),  # type: ignore[arg-type]
        controller=NmpcController(URV_PARAMETERS), duration_s=1010.0,
    )  # fmt: skip


def test_every_stop_within_half_a_metre_and_two_seconds(record: ClosedLoopRecord) -> None:
    assert sorted(record.arrivals) == [0, 1, 2]
    for index, (_, planned_arrival_s, _) in enumerate(STOPS):
        arrival_s, stop_error_m = record.arrivals[index]
        assert abs(stop_error_m) <= 0.5
        assert abs(arrival_s - planned_arrival_s) <= 2.0


def test_speed_tracking_and_limits(record: ClosedLoopRecord) -> None:
    error = record.speeds_mps - record.reference_speeds_mps
    assert float(np.sqrt(np.mean(error**2))) * 3.6 <= 0.5
    assert record.max_overspeed_mps <= 0.0
    assert record.nmpc.failures == 0


def test_jerk_while_moving(record: ClosedLoopRecord) -> None:
    jerk = np.diff(record.accelerations_mps2) / np.diff(record.times_s)
    speeds = record.speeds_mps
    moving = (speeds[1:] > 0.2) & (speeds[:-1] > 0.2)  # the instant of stopping excluded
    assert float(np.abs(jerk[moving]).max()) <= 1.0
