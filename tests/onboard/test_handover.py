"""RD → AD → RD in closed loop: the supervisory controller switches without bumps."""

from __future__ import annotations

import pytest

from deploy.bench.adf_closed_loop import HandoverRecord, run_handover_sequence
from onboard.plant import URV_PARAMETERS
from onboard.plant.point_mass import with_model_mismatch
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.scenario

U_RANGE_N = URV_PARAMETERS.max_traction_force_n + URV_PARAMETERS.max_brake_force_n


@pytest.fixture(scope="module")
def record() -> HandoverRecord:
    ring = TrackMap(load_seed_line("bologna-ring"))
    return run_handover_sequence(
        ring, model=URV_PARAMETERS, truth=with_model_mismatch(URV_PARAMETERS)
    )


def test_the_sequence_passes_through_every_hand_over_state(record: HandoverRecord) -> None:
    assert [record.states[i] for i in record.switch_indices] == ["HRD2AD", "AD", "HAD2RD", "RD"]


def test_no_jump_at_any_switch(record: HandoverRecord) -> None:
    assert len(record.switch_jumps_n) == 4
    assert max(record.switch_jumps_n) <= 0.02 * U_RANGE_N


def test_each_mode_reaches_its_target(record: HandoverRecord) -> None:
    at_99_s = int(99.0 / 0.2)
    assert record.speeds_mps[at_99_s] * 3.6 == pytest.approx(40.0, abs=0.5)  # AD cruise
    assert record.speeds_mps[-1] * 3.6 == pytest.approx(20.0, abs=0.5)  # RD target
