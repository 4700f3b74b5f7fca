"""Odometry interval growth and reset at balise groups; what a balise group delivers."""

from __future__ import annotations

import pytest
from numpy.testing import assert_allclose

from onboard.etcs import (
    EtcsInputError,
    EtcsLevel,
    EtcsOnboard,
    Odometry,
    OdometryAccuracy,
    TrainDataError,
    read_balise_group,
)
from protocol.messages import EtcsMode
from protocol.units import MPS_PER_KMH
from tests.onboard.etcs.layouts import DT_S, level_line
from trackdb import LineBuilder, TrackMap
from trackdb.schema import LevelTransitionPacket


def test_interval_grows_by_five_percent_plus_five_metres_and_resets() -> None:
    odometry = Odometry(OdometryAccuracy(), odometer_m=1_000.0, location_accuracy_m=12.0)
    for travelled in (0.0, 100.0, 1_000.0):
        interval = odometry.update(1_000.0 + travelled)
        expected = 5.0 + 0.05 * travelled + 12.0
        assert_allclose([interval.over_reading_m, interval.under_reading_m], expected, atol=1e-9)
        assert interval.max_safe_front_m == pytest.approx(1_000.0 + travelled + expected)
        assert interval.min_safe_front_m == pytest.approx(1_000.0 + travelled - expected)
    # A balise group at 1995 m read when the odometer said 2000 m: relocated, interval reset.
    odometry.reset(location_m=1_995.0, odometer_m=2_000.0, location_accuracy_m=5.0)
    interval = odometry.update(2_100.0)
    assert interval.estimated_front_m == pytest.approx(2_095.0)
    assert interval.over_reading_m == pytest.approx(5.0 + 5.0 + 5.0)
    assert interval.travelled_since_reference_m == pytest.approx(100.0)


def test_onboard_interval_resets_at_each_group_with_the_linked_accuracy() -> None:
    groups = ((7, 1_000.0, None), (8, 3_000.0, None))
    etcs = EtcsOnboard(level_line(level=1, groups=groups), position_m=0.0)
    etcs.start_of_mission(0.0)
    widths: dict[float, float] = {}
    for k in range(1, 41):
        position_m = 100.0 * k
        out = etcs.step(k * DT_S, position_m, 20 * MPS_PER_KMH)
        widths[position_m] = out.odometry.over_reading_m
        assert out.odometry.under_reading_m == out.odometry.over_reading_m
    # From the start: national Q_NVLOCACC 12 m; group 7 was not announced: 12 m again;
    # group 8 was linked by group 7 with Q_LOCACC 5 m.
    assert widths[900.0] == pytest.approx(5.0 + 0.05 * 900.0 + 12.0)
    assert widths[1_000.0] == pytest.approx(5.0 + 12.0)
    assert widths[2_900.0] == pytest.approx(5.0 + 0.05 * 1_900.0 + 12.0)
    assert widths[3_000.0] == pytest.approx(5.0 + 5.0)
    assert widths[4_000.0] == pytest.approx(5.0 + 0.05 * 1_000.0 + 5.0)
    reading = etcs.last_balise_reading
    assert reading is not None
    assert reading.balise_group_id == 8
    assert reading.header.nid_bg == 8
    assert reading.header.q_link == 1
    assert reading.header.m_mcount == 1


def test_odometer_drift_is_corrected_at_a_balise_group() -> None:
    track_map = level_line(level=1, groups=((7, 1_000.0, None),))
    etcs = EtcsOnboard(track_map, position_m=0.0, read_balise_groups=False)
    etcs.start_of_mission(0.0)
    etcs.step(0.1, 1_020.0, 10.0)  # the odometer reads 2 % long
    etcs.pass_balise_group(track_map.line.balise_groups[0], 0.1, position_m=1_020.0)
    out = etcs.step(0.2, 1_120.0, 10.0)
    assert out.estimated_front_m == pytest.approx(1_100.0)
    assert out.odometry.over_reading_m == pytest.approx(5.0 + 0.05 * 100.0 + 12.0)
    assert out.lrbg_id == 7


def test_a_balise_group_delivers_its_packets() -> None:
    builder = LineBuilder(id="packets", name="Packets", etcs_level=1)
    builder.straight(5_000.0, speed_kmh=120.0, gradient_permille=2.0)
    builder.balise_group(
        3,
        500.0,
        authority_m=2_000.0,
        profile_m=2_500.0,
        packets=(LevelTransitionPacket(distance_m=300.0, level=2),),
    )
    builder.balise_group(4, 1_500.0)
    track_map = TrackMap(builder.build(geodetic_step_m=500.0))
    group = track_map.line.balise_groups[0]
    reading = read_balise_group(group, location_m=500.0, time_s=3.0, linked=False)
    assert reading.movement_authority is not None
    assert reading.movement_authority.level is EtcsLevel.LEVEL_1
    assert reading.movement_authority.end_of_authority_m == 2_000.0
    assert reading.static_speed_profile_end_m == reading.gradient_end_m == 3_000.0
    assert reading.level_transition is not None
    assert reading.level_transition.location_m == 800.0
    assert [g.balise_group_id for g in reading.linked_groups] == [4]
    assert reading.linked_groups[0].location_m == 1_500.0
    assert (reading.header.nid_bg, reading.header.q_link, reading.header.q_updown) == (3, 0, 1)
    # Through the onboard: FS at the group, then Level 2 from 800 m on.
    etcs = EtcsOnboard(track_map, position_m=400.0)
    etcs.start_of_mission(0.0)
    out = etcs.step(0.1, 510.0, 10.0)
    assert (out.mode, out.level, out.end_of_authority_m) == (EtcsMode.FS, EtcsLevel.LEVEL_1, 2.5e3)
    out = etcs.step(0.2, 810.0, 10.0)
    assert out.level is EtcsLevel.LEVEL_2


def test_ring_locations_run_on_across_the_origin() -> None:
    builder = LineBuilder(id="ring", name="Ring", ring=True, etcs_level=1)
    for _ in range(4):
        builder.straight(400.0, speed_kmh=60.0)
        builder.curve(471.24, 300.0, speed_kmh=60.0)
    builder.balise_group(1, 3_000.0, authority_m=1_200.0)
    builder.balise_group(2, 600.0, authority_m=1_200.0)
    track_map = TrackMap(builder.build(geodetic_step_m=50.0))
    length = track_map.length_m
    etcs = EtcsOnboard(track_map, position_m=2_900.0)
    etcs.start_of_mission(0.0)
    out = etcs.step(0.1, 3_050.0, 10.0)
    assert out.mode is EtcsMode.FS
    assert out.end_of_authority_m == pytest.approx(4_200.0 - length)
    now_s, position_m = 0.1, 3_050.0
    while position_m < length + 700.0:
        now_s += 1.0
        position_m += 10.0
        out = etcs.step(now_s, position_m % length, 10.0)
        assert out.mode is EtcsMode.FS
    assert out.lrbg_id == 2
    assert out.estimated_front_m == pytest.approx(position_m - length)
    assert out.end_of_authority_m == pytest.approx(1_800.0)
    assert out.end_of_authority_distance_m == pytest.approx(1_800.0 - (position_m - length))


def test_bad_odometry_inputs() -> None:
    with pytest.raises(TrainDataError):
        OdometryAccuracy(proportional_error=1.5)
    odometry = Odometry(OdometryAccuracy(), odometer_m=0.0, location_accuracy_m=0.0)
    with pytest.raises(EtcsInputError):
        odometry.update(float("nan"))
    with pytest.raises(EtcsInputError):
        odometry.reset(location_m=0.0, odometer_m=0.0, location_accuracy_m=-1.0)
