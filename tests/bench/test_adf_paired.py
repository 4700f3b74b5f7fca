"""``ato bench adf``'s paired lap: IPOPT solving each of our NMPC's problems beside it."""

from __future__ import annotations

import numpy as np

from deploy.bench.adf_bench import field_test_lap
from deploy.bench.adf_paired import PairedController
from onboard.plant import URV_PARAMETERS


def test_ipopt_beside_solves_every_problem_and_changes_nothing_of_the_lap() -> None:
    alone, _ = field_test_lap("sqpmethod", "energy", duration_s=30.0)
    paired = PairedController(URV_PARAMETERS)
    beside, _ = field_test_lap("sqpmethod", "energy", duration_s=30.0, controller=paired)
    assert np.array_equal(beside.speeds_mps, alone.speeds_mps)
    # Each of the 150 control steps either solves or coasts with the plan (no solve).
    solves = alone.nmpc.solves
    assert 0 < alone.coast_steps < 150
    assert solves + alone.coast_steps == 150
    assert paired.stats.solves == solves
    assert paired.ipopt_stats.solves == solves
    assert paired.ipopt_stats.failures == 0
    assert len(paired.ipopt_stats.solve_times_s) == solves
    assert len(paired.cpu_times_s) == len(paired.ipopt_cpu_times_s) == solves
