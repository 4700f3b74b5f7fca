"""Modes: the transition table row by row, then each transition driven through EtcsOnboard."""

from __future__ import annotations

import pytest

from onboard.etcs import (
    MODE_TRANSITIONS,
    EtcsLevel,
    EtcsOnboard,
    MaChange,
    ModeCondition,
    ModeTransition,
    MovementAuthority,
    NationalValues,
    OnSightArea,
    TransitionRefusedError,
)
from onboard.etcs.modes import MODELLED_MODES, select_transition
from protocol.messages import EtcsMode
from protocol.units import MPS_PER_KMH
from tests.onboard.etcs.layouts import DT_S, in_full_supervision, level_line

M = EtcsMode
ROWS = [
    (transition, source, level)
    for transition in MODE_TRANSITIONS
    for source in sorted(transition.sources)
    for level in sorted(transition.levels)
]


@pytest.mark.parametrize(
    ("transition", "source", "level"),
    ROWS,
    ids=[f"{s}-{t.target}-{t.condition}-L{int(lv)}" for t, s, lv in ROWS],
)
def test_each_row_is_taken_from_each_of_its_sources(
    transition: ModeTransition, source: EtcsMode, level: EtcsLevel
) -> None:
    assert select_transition(source, {transition.condition}, level) is transition


def test_no_row_leaves_a_mode_it_does_not_name() -> None:
    for transition in MODE_TRANSITIONS:
        assert transition.sources <= MODELLED_MODES
        assert transition.target in MODELLED_MODES
        for mode in MODELLED_MODES - transition.sources:
            for level in transition.levels:
                chosen = select_transition(mode, {transition.condition}, level)
                assert chosen is not transition
                assert chosen is None or mode in chosen.sources


def test_level_decides_the_trip_condition_number() -> None:
    passed = {ModeCondition.END_OF_AUTHORITY_PASSED}
    one = select_transition(M.FS, passed, EtcsLevel.LEVEL_1)
    two = select_transition(M.FS, passed, EtcsLevel.LEVEL_2)
    assert one is not None
    assert two is not None
    assert (one.condition_number, two.condition_number) == (12, 16)


def test_priorities_isolation_first_then_trip() -> None:
    conditions = {
        ModeCondition.ISOLATED,
        ModeCondition.END_OF_AUTHORITY_PASSED,
        ModeCondition.AUTOMATIC_DRIVING_DISENGAGED,
    }
    chosen = select_transition(M.AD, conditions, EtcsLevel.LEVEL_2)
    assert chosen is not None
    assert chosen.target is M.IS
    chosen = select_transition(M.AD, conditions - {ModeCondition.ISOLATED}, EtcsLevel.LEVEL_2)
    assert chosen is not None
    assert chosen.target is M.TR
    chosen = select_transition(
        M.SB,
        {ModeCondition.AUTHORITY_AND_TRACK_DESCRIPTION, ModeCondition.START_IN_STAFF_RESPONSIBLE},
        EtcsLevel.LEVEL_1,
    )
    assert chosen is not None
    assert chosen.target is M.FS


# -- through the onboard -------------------------------------------------------------------------


def _taken(etcs: EtcsOnboard) -> list[tuple[EtcsMode, EtcsMode, int | None]]:
    return [(c.source, c.target, c.transition.condition_number) for c in etcs.mode_changes]


def _run(etcs: EtcsOnboard, from_m: float, to_m: float, speed_kmh: float) -> None:
    """Run at a constant speed, ignoring the commands."""
    position_m, now_s = from_m, etcs.output.time_s
    while position_m < to_m:
        now_s += DT_S
        position_m = min(position_m + speed_kmh * MPS_PER_KMH * DT_S, to_m)
        etcs.step(now_s, position_m, speed_kmh * MPS_PER_KMH)


def test_start_in_staff_responsible_then_full_supervision_at_a_balise_group() -> None:
    track_map = level_line(level=1, groups=((1, 500.0, 2_000.0), (2, 3_000.0, None)))
    etcs = EtcsOnboard(track_map, position_m=100.0)
    assert etcs.level is EtcsLevel.LEVEL_1
    assert etcs.mode is M.SB
    etcs.start_of_mission(0.0)
    assert etcs.mode is M.SR
    out = etcs.step(0.1, 100.0, 10 * MPS_PER_KMH)
    assert out.permitted_speed_mps == pytest.approx(40 * MPS_PER_KMH)  # V_NVSTFF
    _run(etcs, 100.0, 600.0, 30.0)
    assert etcs.mode is M.FS
    assert _taken(etcs) == [(M.SB, M.SR, None), (M.SR, M.FS, 32)]
    assert etcs.output.end_of_authority_m == pytest.approx(2_500.0)
    assert etcs.output.lrbg_id == 1


def test_radio_authority_in_level_2_staff_responsible() -> None:
    etcs = EtcsOnboard(level_line(), position_m=100.0)
    etcs.start_of_mission(0.0)
    change = etcs.receive_movement_authority(
        MovementAuthority(reference_m=0.0, end_of_authority_m=5_000.0), 0.5
    )
    assert change is MaChange.NEW
    assert _taken(etcs) == [(M.SB, M.SR, None), (M.SR, M.FS, 31)]


def test_authority_in_stand_by_enters_full_supervision() -> None:
    etcs = in_full_supervision(level_line(), position_m=100.0, end_of_authority_m=5_000.0)
    assert _taken(etcs) == [(M.SB, M.FS, 10)]


def test_trip_at_the_end_of_authority_then_post_trip_and_back_to_full_supervision() -> None:
    eoa_m = 2_000.0
    etcs = in_full_supervision(level_line(), position_m=1_800.0, end_of_authority_m=eoa_m)
    position_m, now_s = 1_800.0, 0.0
    while etcs.mode is M.FS:
        now_s += DT_S
        position_m += 20 * MPS_PER_KMH * DT_S
        out = etcs.step(now_s, position_m, 20 * MPS_PER_KMH)
    assert out.mode is M.TR
    assert out.emergency_brake
    assert (
        out.odometry.min_safe_front_m
        > eoa_m
        >= out.odometry.min_safe_front_m - 20 * MPS_PER_KMH * DT_S
    )
    assert _taken(etcs)[-1] == (M.FS, M.TR, 16)
    with pytest.raises(TransitionRefusedError):
        etcs.acknowledge_trip(now_s)
    # The EB holds while the train runs and is not released by the mode alone.
    for speed_kmh in (15.0, 5.0, 0.0):
        now_s += DT_S
        out = etcs.step(now_s, position_m, speed_kmh * MPS_PER_KMH)
        assert out.emergency_brake
        assert out.mode is M.TR
    assert (
        etcs.receive_movement_authority(
            MovementAuthority(reference_m=0.0, end_of_authority_m=4_000.0), now_s
        )
        is MaChange.REJECTED
    )
    etcs.acknowledge_trip(now_s)
    assert etcs.mode is M.PT
    now_s += DT_S
    out = etcs.step(now_s, position_m, 0.0)
    assert not out.emergency_brake
    assert out.permitted_speed_mps == 0.0
    etcs.receive_movement_authority(
        MovementAuthority(reference_m=0.0, end_of_authority_m=4_000.0), now_s
    )
    assert _taken(etcs)[-2:] == [(M.TR, M.PT, 7), (M.PT, M.FS, 31)]


def test_trip_in_level_1_and_restart_in_staff_responsible_from_post_trip() -> None:
    track_map = level_line(level=1, groups=((1, 500.0, 1_000.0),))
    etcs = EtcsOnboard(track_map, position_m=400.0)
    etcs.start_of_mission(0.0)
    _run(etcs, 400.0, 1_600.0, 30.0)
    assert (M.FS, M.TR, 12) in _taken(etcs)
    etcs.step(etcs.output.time_s + DT_S, 1_600.0, 0.0)
    etcs.acknowledge_trip(etcs.output.time_s)
    etcs.start_of_mission(etcs.output.time_s)
    assert _taken(etcs)[-2:] == [(M.TR, M.PT, 7), (M.PT, M.SR, None)]


def test_staff_responsible_distance_trips() -> None:
    etcs = EtcsOnboard(level_line(), position_m=0.0, national=NationalValues(d_nvstff_m=300.0))
    etcs.start_of_mission(0.0)
    position_m, now_s, min_safe = 0.0, 0.0, []
    while etcs.mode is M.SR:
        now_s += DT_S
        position_m += 30 * MPS_PER_KMH * DT_S
        min_safe.append(etcs.step(now_s, position_m, 30 * MPS_PER_KMH).odometry.min_safe_front_m)
    assert _taken(etcs)[-1] == (M.SR, M.TR, 42)
    assert min_safe[-2] <= 300.0 < min_safe[-1]


def test_emergency_stop_trips_in_full_supervision_and_is_ignored_in_stand_by() -> None:
    etcs = EtcsOnboard(level_line(), position_m=0.0)
    etcs.emergency_stop(0.0)
    assert etcs.mode is M.SB
    etcs.receive_movement_authority(MovementAuthority(reference_m=0.0, end_of_authority_m=5e3), 0)
    assert etcs.mode is M.FS
    etcs.emergency_stop(0.1)
    assert _taken(etcs)[-1] == (M.FS, M.TR, 20)
    assert etcs.step(0.2, 0.0, 0.0).emergency_brake


def test_automatic_driving_engaged_and_left_on_a_brake_or_a_disengagement() -> None:
    etcs = EtcsOnboard(level_line(speed_kmh=100.0), position_m=100.0)
    etcs.receive_movement_authority(
        MovementAuthority(reference_m=95.0, end_of_authority_m=9_000.0), 0.0
    )
    etcs.request_automatic_driving(True, 0.0)
    assert etcs.mode is M.FS  # the rear end is not yet on the track description (from 95 m)
    etcs.step(0.1, 140.0, 0.0)
    assert etcs.mode is M.AD  # the request stands until it can be granted
    etcs.step(0.2, 140.0, 107 * MPS_PER_KMH)  # SB from CSM
    assert etcs.mode is M.FS
    assert _taken(etcs)[-1] == (M.AD, M.FS, 24)
    etcs.step(0.3, 140.0, 0.0)
    etcs.step(0.4, 140.0, 0.0)
    assert etcs.mode is M.FS  # needs a new engagement
    etcs.request_automatic_driving(True, 0.4)
    assert etcs.mode is M.AD
    etcs.request_automatic_driving(False, 0.5)
    assert _taken(etcs)[-2:] == [(M.FS, M.AD, 80), (M.AD, M.FS, 53)]


def test_on_sight_area_in_and_out() -> None:
    etcs = EtcsOnboard(level_line(), position_m=900.0)
    etcs.receive_movement_authority(
        MovementAuthority(
            reference_m=0.0,
            end_of_authority_m=5_000.0,
            on_sight=OnSightArea(start_m=1_000.0, end_m=1_500.0),
        ),
        0.0,
    )
    assert etcs.mode is M.FS
    _run(etcs, 900.0, 1_200.0, 25.0)
    assert etcs.mode is M.OS
    assert etcs.output.ceiling_speed_mps == pytest.approx(30 * MPS_PER_KMH)  # V_NVONSIGHT
    _run(etcs, 1_200.0, 1_520.0, 25.0)
    assert etcs.mode is M.FS
    assert [t for _, t, _ in _taken(etcs)] == [M.FS, M.OS, M.FS]


def test_balise_group_at_the_end_of_authority_in_release_speed_monitoring_trips() -> None:
    groups = ((1, 100.0, None), (2, 1_000.0, None))
    track_map = level_line(level=1, groups=groups)
    etcs = EtcsOnboard(track_map, position_m=850.0)
    etcs.pass_balise_group(track_map.line.balise_groups[0], 0.0, position_m=100.0)
    etcs.receive_movement_authority(
        MovementAuthority(
            reference_m=100.0, end_of_authority_m=900.0, release_speed_mps=15 * MPS_PER_KMH
        ),
        0.0,
    )
    assert etcs.mode is M.FS
    _run(etcs, 850.0, 1_000.5, 10.0)
    assert _taken(etcs)[-1] == (M.FS, M.TR, 11)
    assert etcs.output.lrbg_id == 2


def test_isolation_from_any_mode_and_insertion_back_to_stand_by() -> None:
    etcs = in_full_supervision(
        level_line(speed_kmh=100.0), position_m=100.0, end_of_authority_m=9_000.0
    )
    assert etcs.step(0.1, 100.0, 110 * MPS_PER_KMH).emergency_brake
    etcs.isolate(0.2)
    out = etcs.step(0.3, 110.0, 110 * MPS_PER_KMH)
    assert out.mode is M.IS
    assert not (out.emergency_brake)
    assert not (out.service_brake)
    assert etcs.movement_authority is None
    etcs.insert(0.4)
    assert _taken(etcs)[-2:] == [(M.FS, M.IS, None), (M.IS, M.SB, None)]
    with pytest.raises(TransitionRefusedError):
        etcs.insert(0.5)


def test_requests_refused_in_the_wrong_mode() -> None:
    etcs = in_full_supervision(level_line(), position_m=100.0, end_of_authority_m=9_000.0)
    with pytest.raises(TransitionRefusedError):
        etcs.acknowledge_trip(0.1)
    with pytest.raises(TransitionRefusedError):
        etcs.start_of_mission(0.1)
