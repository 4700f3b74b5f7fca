"""The onboard on its own sensors: odometry from wheel readings, balise groups from detections,
linking reactions, and what the KPIs read."""

from __future__ import annotations

import pytest

from onboard.etcs import (
    URV_ODOMETER,
    EtcsInputError,
    EtcsLevel,
    EtcsOnboard,
    LinkingFault,
    MovementAuthority,
    WheelAdhesion,
)
from protocol.messages import EtcsMode
from tests.onboard.etcs.layouts import level_line
from tests.onboard.etcs.wheels import Cycle, WheelRig
from trackdb import LineBuilder, TrackMap
from trackdb.schema import Link, LinkingPacket, LinkReaction

GROUPS = ((1, 100.0, None), (2, 2_300.0, None), (3, 4_500.0, None))


def _onboard(track_map: TrackMap, position_m: float = 0.0) -> EtcsOnboard:
    """On its sensors, in FS with a Level 2 MA far ahead."""
    etcs = EtcsOnboard(
        track_map, position_m=position_m, level=EtcsLevel.LEVEL_2, odometer=URV_ODOMETER
    )
    etcs.receive_movement_authority(
        MovementAuthority(reference_m=0.0, end_of_authority_m=25_000.0), 0.0
    )
    assert etcs.mode is EtcsMode.FS
    return etcs


def _rig(track_map: TrackMap, **kwargs: object) -> WheelRig:
    return WheelRig(groups=track_map.line.balise_groups, **kwargs)  # type: ignore[arg-type]


def _covered(cycle: Cycle) -> bool:
    return cycle.output.odometry.contains(cycle.true_front_m)


def _error_m(cycle: Cycle) -> float:
    """etcs_estimate_error_m as a scenario computes it: the estimate less the truth."""
    return cycle.output.odometry.estimated_front_m - cycle.true_front_m


def test_a_two_percent_diameter_error_stays_inside_the_interval_and_is_corrected() -> None:
    track_map = level_line(groups=GROUPS)
    etcs = _onboard(track_map)
    rig = _rig(
        track_map,
        position_m=0.0,
        speed_mps=30.0,
        reads_long_front=0.02,
        reads_long_rear=0.02,
        reader_errors_m=(0.4, -0.5, 0.3),
    )
    cycles = rig.drive(etcs, 160.0)  # 4.8 km
    assert all(_covered(cycle) for cycle in cycles)
    assert {c.output.lrbg_id for c in cycles} == {None, 1, 2, 3}
    # The last cycle before group 2, 2.2 km after group 1: 2 % long, inside the interval.
    before = max((c for c in cycles if c.output.lrbg_id == 1), key=lambda c: c.true_front_m)
    interval = before.output.odometry
    assert before.true_front_m == pytest.approx(2_300.0, abs=30.0)
    assert _error_m(before) == pytest.approx(0.02 * (before.true_front_m - 100.4), abs=0.5)
    # Group 1 was not announced: Q_NVLOCACC 12 m and the reader's 1.5 m; then 2.03 m + 3 %.
    travelled_m = interval.travelled_since_reference_m
    assert interval.over_reading_m == pytest.approx(13.5 + 2.0289 + 0.03 * travelled_m, abs=0.01)
    assert before.output.travelled_since_lrbg_m == travelled_m
    # Corrected at group 2, read 0.5 m early, linked with Q_LOCACC 5 m.
    after = min((c for c in cycles if c.output.lrbg_id == 2), key=lambda c: c.true_front_m)
    assert abs(_error_m(after)) < 0.5 + 0.02 * 3.0 + 0.05
    assert after.output.odometry.location_accuracy_m == pytest.approx(5.0 + 1.5)
    assert after.output.wheel_adhesion is WheelAdhesion.ROLLING


def test_the_interval_grows_during_a_slide_and_resets_at_the_next_group() -> None:
    track_map = level_line(groups=GROUPS)
    etcs = _onboard(track_map)
    rig = _rig(track_map, position_m=0.0, speed_mps=30.0)
    rolling = rig.drive(etcs, 20.0)  # past group 1, 600 m
    width_before = rolling[-1].output.odometry.over_reading_m

    def locked(_time_s: float, _speed_mps: float) -> tuple[float, float]:
        return 0.0, 0.0

    sliding = rig.drive(etcs, 4.0, -0.4, locked)  # wheels locked on a slippery rail
    assert {c.output.wheel_adhesion for c in sliding} >= {WheelAdhesion.SLIDE}
    assert all(_covered(cycle) for cycle in rolling + sliding)
    last = sliding[-1].output.odometry
    assert _error_m(sliding[-1]) < -5.0  # the wheels stopped measuring the ground
    assert last.slip_slide_over_reading_m > -_error_m(sliding[-1])
    # Ahead, the interval grew far faster than its 3 % would over the ~110 m run.
    assert last.over_reading_m - width_before > 10.0 * 0.03 * 110.0
    after = rig.drive(etcs, 70.0)  # rolling again, past group 2
    assert all(_covered(cycle) for cycle in after)
    reset = next(c.output.odometry for c in after if c.output.lrbg_id == 2)
    assert reset.slip_slide_over_reading_m == reset.slip_slide_under_reading_m == 0.0


def test_a_group_is_read_at_the_odometer_interpolated_to_its_detection_time() -> None:
    track_map = level_line(groups=((5, 1_000.0, None),))
    etcs = _onboard(track_map, position_m=901.0)
    rig = _rig(track_map, position_m=901.0, speed_mps=25.0)
    cycles = rig.drive(etcs, 4.0)
    read = cycles[-1]
    assert read.output.lrbg_id == 5
    assert cycles[-2].output.lrbg_id is None
    reading = etcs.last_balise_reading
    assert reading is not None
    assert reading.balise_group_id == 5
    # Detected mid-cycle, at the instant the front end was at 1000 m: the odometer there.
    assert reading.time_s == pytest.approx(3.96, abs=1e-6)
    odometer = etcs.odometer
    assert odometer is not None
    since_m = odometer.output.distance_m - odometer.position_at(reading.time_s).distance_m
    assert read.output.odometry.estimated_front_m == pytest.approx(1_000.0 + since_m, abs=1e-9)
    # Taking the odometer at the cycle's end instead would be 1 m off; this is within pulses.
    assert abs(_error_m(read)) < 3 * URV_ODOMETER.pulse_m


def _linked_line(reaction: LinkReaction) -> TrackMap:
    builder = LineBuilder(id="linked", name="Linked", etcs_level=2)
    builder.straight(10_000.0, speed_kmh=160.0)
    link = Link(distance_m=900.0, balise_group_id=2, reaction=reaction, location_accuracy_m=5.0)
    builder.balise_group(1, 100.0, link_next=False, packets=(LinkingPacket(links=(link,)),))
    builder.balise_group(2, 1_000.0)
    builder.balise_group(3, 3_000.0)
    return TrackMap(builder.build(geodetic_step_m=1_000.0))


def test_a_missed_linked_group_commands_the_service_brake_to_standstill() -> None:
    track_map = _linked_line(LinkReaction.SERVICE_BRAKE)
    etcs = _onboard(track_map)
    rig = _rig(track_map, position_m=0.0, speed_mps=20.0, missed_ids=frozenset({2}))
    cycles = rig.drive(etcs, 60.0)
    reacted = next(c for c in cycles if c.output.linking_events)
    (event,) = reacted.output.linking_events
    assert (event.balise_group_id, event.fault, event.reaction, event.applied) == (
        2,
        LinkingFault.MISSED,
        LinkReaction.SERVICE_BRAKE,
        True,
    )
    assert (event.expected_location_m, event.location_accuracy_m) == (1_000.0, 5.0)
    # Reported once, when the min-safe front end passed the window's end, 1005 m.
    assert sum(len(c.output.linking_events) for c in cycles) == 1
    assert reacted.output.odometry.min_safe_front_m > 1_005.0
    assert 1_005.0 < reacted.true_front_m < 1_005.0 + 50.0
    assert etcs.linking_events == [event]
    assert reacted.output.service_brake
    assert not reacted.output.emergency_brake
    # Held while the train runs on; revoked once it stands still.
    assert all(c.output.service_brake for c in cycles if c.output.time_s >= reacted.output.time_s)
    stopping = rig.drive(etcs, 40.0, -0.7)
    assert stopping[0].output.service_brake
    assert not stopping[-1].output.service_brake
    assert stopping[-1].true_speed_mps == 0.0
    assert etcs.mode is EtcsMode.FS


def test_a_missed_linked_group_with_train_trip_trips() -> None:
    track_map = _linked_line(LinkReaction.TRAIN_TRIP)
    etcs = _onboard(track_map)
    rig = _rig(track_map, position_m=0.0, speed_mps=20.0, missed_ids=frozenset({2}))
    cycles = rig.drive(etcs, 60.0)
    reacted = next(c for c in cycles if c.output.linking_events)
    assert reacted.output.mode is EtcsMode.TR
    assert reacted.output.emergency_brake
    change = etcs.mode_changes[-1]
    assert (change.source, change.target, change.transition.condition_number) == (
        EtcsMode.FS,
        EtcsMode.TR,
        17,
    )


def test_no_reaction_only_reports() -> None:
    track_map = _linked_line(LinkReaction.NO_REACTION)
    etcs = _onboard(track_map)
    rig = _rig(track_map, position_m=0.0, speed_mps=20.0, missed_ids=frozenset({2}))
    cycles = rig.drive(etcs, 60.0)
    events = [e for c in cycles for e in c.output.linking_events]
    assert [(e.balise_group_id, e.reaction) for e in events] == [(2, LinkReaction.NO_REACTION)]
    assert not any(c.output.service_brake or c.output.emergency_brake for c in cycles)
    assert etcs.mode is EtcsMode.FS


def test_a_group_beyond_the_expected_one_shows_it_missed() -> None:
    # Group 3 lies 10 m after group 2, inside the interval: it is read before the min-safe
    # front end passes group 2's window, and shows group 2 missed.
    builder = LineBuilder(id="close", name="Close groups", etcs_level=2)
    builder.straight(5_000.0, speed_kmh=160.0)
    for group_id, position_m in ((1, 100.0), (2, 1_000.0), (3, 1_010.0)):
        builder.balise_group(group_id, position_m)
    track_map = TrackMap(builder.build(geodetic_step_m=1_000.0))
    etcs = _onboard(track_map)
    rig = _rig(track_map, position_m=0.0, speed_mps=20.0, missed_ids=frozenset({2}))
    cycles = rig.drive(etcs, 60.0)
    reacted = next(c for c in cycles if c.output.linking_events)
    assert reacted.output.lrbg_id == 3
    assert [(e.balise_group_id, e.fault) for e in reacted.output.linking_events] == [
        (2, LinkingFault.MISSED)
    ]
    assert reacted.output.service_brake  # the builder's links ask for the service brake


def test_a_linked_group_read_outside_its_window_reacts() -> None:
    track_map = _linked_line(LinkReaction.SERVICE_BRAKE)
    etcs = _onboard(track_map)
    # The reader reports group 2 when the front end is still 60 m short of it.
    rig = _rig(track_map, position_m=0.0, speed_mps=20.0, reader_errors_m=(0.0, -60.0))
    cycles = rig.drive(etcs, 60.0)
    reacted = next(c for c in cycles if c.output.linking_events)
    assert [(e.balise_group_id, e.fault) for e in reacted.output.linking_events] == [
        (2, LinkingFault.OUTSIDE_WINDOW)
    ]
    assert reacted.output.lrbg_id == 2
    assert reacted.output.service_brake


def test_runs_on_sensors_are_deterministic() -> None:
    def run() -> list[Cycle]:
        track_map = level_line(groups=GROUPS)
        etcs = _onboard(track_map)
        rig = _rig(
            track_map,
            position_m=0.0,
            speed_mps=5.0,
            reads_long_front=0.015,
            reads_long_rear=-0.01,
            reader_errors_m=(0.3, -0.2, 0.1),
        )
        return rig.drive(etcs, 30.0, 1.0) + rig.drive(etcs, 30.0)

    assert run() == run()


def test_the_sensor_path_refuses_given_motion_and_the_other_way_round() -> None:
    track_map = level_line(groups=GROUPS)
    etcs = EtcsOnboard(track_map, odometer=URV_ODOMETER)
    assert not etcs.read_balise_groups
    with pytest.raises(EtcsInputError):
        etcs.step(0.1, 1.0, 1.0)
    with pytest.raises(EtcsInputError):
        etcs.pass_balise_group(track_map.line.balise_groups[0], 0.1)
    with pytest.raises(EtcsInputError):
        EtcsOnboard(track_map, odometer=URV_ODOMETER, read_balise_groups=True)
    with pytest.raises(EtcsInputError):
        EtcsOnboard(track_map).step_on_sensors(0.1, [])
    # With no reading yet the train has not moved.
    out = etcs.step_on_sensors(0.1, [])
    assert (out.estimated_front_m, out.estimated_speed_mps) == (0.0, 0.0)


def test_the_given_motion_path_checks_linking_too() -> None:
    track_map = _linked_line(LinkReaction.TRAIN_TRIP)
    etcs = EtcsOnboard(track_map, position_m=0.0, level=EtcsLevel.LEVEL_2, read_balise_groups=False)
    etcs.receive_movement_authority(
        MovementAuthority(reference_m=0.0, end_of_authority_m=9_000.0), 0.0
    )
    etcs.step(1.0, 100.0, 20.0)
    etcs.pass_balise_group(track_map.line.balise_groups[0], 1.0)
    out = etcs.step(2.0, 1_000.0, 20.0)
    assert out.mode is EtcsMode.FS
    assert not out.linking_events
    out = etcs.step(3.0, 1_080.0, 20.0)  # min-safe front end past 1005 m: group 2 missed
    assert [e.fault for e in out.linking_events] == [LinkingFault.MISSED]
    assert out.mode is EtcsMode.TR
