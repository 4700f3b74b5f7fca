"""Supervision: every status reached in ramp-ups, the commands, and their revocation."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import pytest

from onboard.etcs import (
    URV_TRAIN_DATA,
    EtcsOnboard,
    EtcsOutput,
    Monitoring,
    MovementAuthority,
    NationalValues,
)
from onboard.etcs.supervision import Demand, InterventionLatch
from protocol.messages import EtcsMode, SupervisionStatus
from protocol.units import MPS_PER_KMH
from tests.onboard.etcs import reference_braking as ref
from tests.onboard.etcs.layouts import DT_S, in_full_supervision, level_line

S = SupervisionStatus
ORDER = [S.NORMAL, S.INDICATION, S.OVERSPEED, S.WARNING, S.INTERVENTION]


def _ramp(etcs: EtcsOnboard, position_m: float, speeds_kmh: list[float]) -> list[EtcsOutput]:
    """Steps at a fixed position with the given speeds, 0.1 s apart."""
    start_s = etcs.output.time_s
    return [
        etcs.step(start_s + (k + 1) * DT_S, position_m, speed * MPS_PER_KMH)
        for k, speed in enumerate(speeds_kmh)
    ]


def _first(
    outputs: list[EtcsOutput], speeds: list[float], predicate: Callable[[EtcsOutput], bool]
) -> float:
    for out, speed in zip(outputs, speeds, strict=True):
        if predicate(out):
            return speed
    raise AssertionError("never reached")


def test_ceiling_speed_ramp_reaches_each_status_at_its_margin() -> None:
    etcs = in_full_supervision(
        level_line(speed_kmh=100.0), position_m=1_000.0, end_of_authority_m=28_000.0
    )
    assert etcs.mode is EtcsMode.FS
    speeds = [90.0 + 0.05 * k for k in range(500)]
    outputs = _ramp(etcs, 1_000.0, speeds)
    assert all(out.monitoring is Monitoring.CEILING_SPEED for out in outputs)
    statuses = [out.supervision_status for out in outputs]
    assert [s for k, s in enumerate(statuses) if k == 0 or s != statuses[k - 1]] == [
        S.NORMAL,
        S.OVERSPEED,
        S.WARNING,
        S.INTERVENTION,
    ]
    # MRSP 100 km/h: dV_warning 4, dV_sbi 5.5, dV_ebi 7.5 km/h (below 110 km/h).
    thresholds = {
        "overspeed": (_first(outputs, speeds, lambda o: o.supervision_status is S.OVERSPEED), 100),
        "warning": (_first(outputs, speeds, lambda o: o.supervision_status is S.WARNING), 104.0),
        "traction": (_first(outputs, speeds, lambda o: o.traction_cut), 104.0),
        "service": (_first(outputs, speeds, lambda o: o.service_brake), 105.5),
        "emergency": (_first(outputs, speeds, lambda o: o.emergency_brake), 107.5),
    }
    for name, (first_kmh, threshold_kmh) in thresholds.items():
        assert threshold_kmh < first_kmh <= threshold_kmh + 0.05 + 1e-9, name
    assert etcs.service_brake_interventions == 1
    assert etcs.emergency_brake_interventions == 1


def test_emergency_brake_is_released_only_at_standstill() -> None:
    etcs = in_full_supervision(
        level_line(speed_kmh=100.0), position_m=1_000.0, end_of_authority_m=28_000.0
    )
    out = _ramp(etcs, 1_000.0, [109.0])[-1]
    assert out.emergency_brake
    assert out.supervision_status is S.INTERVENTION
    for out in _ramp(etcs, 1_000.0, [90.0, 50.0, 10.0, 1.0]):
        assert out.emergency_brake
        assert out.supervision_status is S.INTERVENTION
        assert out.traction_cut
    out = _ramp(etcs, 1_000.0, [0.0])[-1]
    assert not (out.emergency_brake)
    assert not (out.service_brake)
    assert not (out.traction_cut)
    assert out.supervision_status is S.NORMAL


def test_emergency_brake_released_once_its_cause_is_gone_when_q_nvemrrls_says_so() -> None:
    national = NationalValues(emergency_brake_release_at_standstill=False)
    etcs = in_full_supervision(
        level_line(speed_kmh=100.0),
        position_m=1_000.0,
        end_of_authority_m=28_000.0,
        national=national,
    )
    assert _ramp(etcs, 1_000.0, [109.0])[-1].emergency_brake
    assert not _ramp(etcs, 1_000.0, [99.0])[-1].emergency_brake


def test_service_brake_revoked_once_at_or_below_the_permitted_speed() -> None:
    etcs = in_full_supervision(
        level_line(speed_kmh=100.0), position_m=1_000.0, end_of_authority_m=28_000.0
    )
    outputs = _ramp(etcs, 1_000.0, [106.0, 103.0, 100.5, 100.0])
    assert [o.service_brake for o in outputs] == [True, True, True, False]
    assert not any(o.emergency_brake for o in outputs)
    assert outputs[-1].supervision_status is S.NORMAL


def test_without_a_service_brake_the_emergency_brake_intervenes() -> None:
    train = replace(URV_TRAIN_DATA, service_brake_available=False)
    track_map = level_line(speed_kmh=100.0)
    etcs = EtcsOnboard(track_map, train=train, position_m=1_000.0)
    etcs.receive_movement_authority(MovementAuthority(reference_m=0.0, end_of_authority_m=2.8e4), 0)
    out = _ramp(etcs, 1_000.0, [106.0])[-1]
    assert out.emergency_brake
    assert not out.service_brake


def test_target_speed_ramp_towards_the_end_of_authority_reaches_every_status() -> None:
    """Speed raised 1 km/h every 0.1 s while running towards a 0 km/h EoA on level track."""
    eoa_m = 20_000.0
    etcs = in_full_supervision(level_line(), position_m=18_300.0, end_of_authority_m=eoa_m)
    position_m, speed_kmh = 18_300.0, 100.0
    records: list[tuple[EtcsOutput, float]] = []
    for k in range(70):
        out = etcs.step((k + 1) * DT_S, position_m, speed_kmh * MPS_PER_KMH)
        records.append((out, speed_kmh))
        position_m += speed_kmh * MPS_PER_KMH * DT_S
        speed_kmh += 1.0
    statuses = [out.supervision_status for out, _ in records]
    assert [s for k, s in enumerate(statuses) if k == 0 or s != statuses[k - 1]] == ORDER
    # Well under the 200 km/h ceiling: the target alone drives the statuses, and Overspeed
    # means faster than the permitted speed shown.
    assert speed_kmh < 175.0
    for out, speed in records:
        assert out.ceiling_speed_mps == pytest.approx(200 * MPS_PER_KMH)
        if out.supervision_status is not S.NORMAL:
            assert out.monitoring is Monitoring.TARGET_SPEED
        if out.supervision_status in (S.INDICATION, S.NORMAL):
            assert speed * MPS_PER_KMH <= out.permitted_speed_mps + 1e-6
        if out.supervision_status is S.OVERSPEED:
            assert speed * MPS_PER_KMH > out.permitted_speed_mps
    # The SvL (= EoA, on the max-safe front end) governs; each status begins exactly when the
    # front end crosses the independently computed limit.
    keys = {S.INDICATION: "i_svl", S.OVERSPEED: "p_svl", S.WARNING: "w_svl"}
    for status, key in keys.items():
        k = statuses.index(status)
        for index, crossed in ((k, True), (k - 1, False)):
            out, speed = records[index]
            distance = eoa_m - out.odometry.max_safe_front_m
            assert (distance < ref.stop_curves(speed)[key]) is crossed, (status, index)
    first_sb = next(k for k, (o, _) in enumerate(records) if o.service_brake)
    first_eb = next(k for k, (o, _) in enumerate(records) if o.emergency_brake)
    first_cut = next(k for k, (o, _) in enumerate(records) if o.traction_cut)
    assert first_cut == statuses.index(S.WARNING) < first_sb < first_eb
    for index, key in ((first_sb, "sbi2"), (first_eb, "ebi")):
        out, speed = records[index]
        assert eoa_m - out.odometry.max_safe_front_m < ref.stop_curves(speed)[key]
        out, speed = records[index - 1]
        assert eoa_m - out.odometry.max_safe_front_m >= ref.stop_curves(speed)[key]


def test_permitted_speed_falls_to_zero_at_the_end_of_authority() -> None:
    eoa_m = 3_000.0
    etcs = in_full_supervision(level_line(), position_m=0.0, end_of_authority_m=eoa_m)
    permitted = []
    for k, position in enumerate(range(0, 3_000, 100)):
        out = etcs.step((k + 1) * DT_S, float(position), 0.0)
        permitted.append(out.permitted_speed_mps)
        assert out.end_of_authority_distance_m == pytest.approx(eoa_m - position)
        assert out.supervised_location_distance_m == pytest.approx(
            eoa_m - out.odometry.max_safe_front_m
        )
    assert permitted == sorted(permitted, reverse=True)
    assert permitted[0] == pytest.approx(200 * MPS_PER_KMH)
    assert permitted[-1] == 0.0


def test_release_speed_monitoring_replaces_the_curves_near_the_end_of_authority() -> None:
    eoa_m = 2_000.0
    etcs = in_full_supervision(
        level_line(),
        position_m=1_900.0,
        end_of_authority_m=eoa_m,
        release_speed_mps=20 * MPS_PER_KMH,
    )
    out = etcs.step(0.1, 1_990.0, 15 * MPS_PER_KMH)
    assert out.monitoring is Monitoring.RELEASE_SPEED
    assert out.permitted_speed_mps == pytest.approx(20 * MPS_PER_KMH)
    assert out.release_speed_mps == pytest.approx(20 * MPS_PER_KMH)
    assert out.supervision_status is S.NORMAL
    assert not out.emergency_brake
    out = etcs.step(0.2, 1_991.0, 21 * MPS_PER_KMH)
    assert out.emergency_brake
    assert out.supervision_status is S.INTERVENTION


def test_latch_forced_emergency_brake_and_reset() -> None:
    latch = InterventionLatch()
    assert latch.update(Demand(), standstill=True, forced_emergency_brake=True).emergency_brake
    assert latch.update(Demand(), standstill=True, forced_emergency_brake=True).emergency_brake
    assert not latch.update(Demand(), standstill=True).emergency_brake
    latch.update(Demand(status=S.WARNING), standstill=False)
    assert latch.commands.traction_cut
    assert latch.status(S.WARNING) is S.WARNING
    latch.reset()
    assert not latch.commands.traction_cut
