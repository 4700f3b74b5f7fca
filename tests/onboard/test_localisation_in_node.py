"""The node's closed loop on the fused localisation, and the localisation's health."""

from __future__ import annotations

import math

import pytest
import zenoh

from onboard.ato_ob import Condition
from onboard.node import OnboardNode, OnboardSettings
from onboard.plant.marker_reader import StopMarkerReader
from onboard.plant.sensors import SensorFaults, SensorNoise, TimeWindow
from onboard.runtime import SimClock
from onboard.sfa.chain import SensorSettings
from protocol import messages as m
from tests.conftest import wait_for
from tests.operator import LockstepOperator
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.scenario

RING = TrackMap(load_seed_line("bologna-ring"))


def _drive(zenoh_pair: tuple[zenoh.Session, zenoh.Session], **settings: object) -> OnboardNode:
    trackside, onboard = zenoh_pair
    node = OnboardNode(
        OnboardSettings(vehicle_id="URV1", **settings),  # type: ignore[arg-type]
        session=onboard,
        clock=SimClock(),
        track_map=RING,
    )
    # No trackside service here to answer the track-data query: the versions are taken as checked.
    node.track_database.record_trackside_version(
        m.LineVersionReply(line_id=RING.line.id, version=RING.version)
    )
    hands = LockstepOperator(trackside, node)
    assert wait_for(lambda: _reachable(hands))
    hands.run(3.0)
    assert hands.command(m.RemoteDrivingTargetCommand(target_speed_mps=30 / 3.6)).accepted
    hands.run(40.0)
    return node


def _reachable(hands: LockstepOperator) -> bool:
    try:
        return hands.command(m.PingCommand()).accepted
    except Exception:
        return False


def test_the_controller_sees_the_fused_estimate_not_the_truth(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    node = _drive(zenoh_pair)
    try:
        assert node.sensor_fusion.estimate is not None
        stack, plant = node.stack, node.plant
        error_m = stack.position_m - plant.position_m
        assert error_m != 0.0
        assert abs(error_m) < 1.0
        assert stack.position_m == node.sensor_fusion.position_m
        assert abs(stack.speed_mps - plant.speed_mps) < 0.1
        status = node.status(node.clock.now_ns)
        assert status.position_m == RING.normalise(stack.position_m)
    finally:
        node.close()


def test_without_the_imu_and_the_odometer_the_train_is_not_localised(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    """The filter's health is the ATO-OB's "localised" condition: with both of its dead-reckoning
    sensors gone the estimate is lost, and ATO is not available for want of localisation."""
    lost = (TimeWindow(20.0, math.inf),)
    sensors = SensorSettings(faults=SensorFaults(imu_outages=lost, odometer_outages=lost))
    node = _drive(zenoh_pair, sensors=sensors)
    try:
        assert not node.sensor_fusion.localisation_valid
        reasons = node.stack.controller.output.unavailable_reasons
        assert Condition.LOCALISED in reasons
    finally:
        node.close()


def test_with_every_sensor_the_train_is_localised(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    node = _drive(zenoh_pair)
    try:
        assert node.sensor_fusion.localisation_valid
        assert Condition.LOCALISED not in node.stack.controller.output.unavailable_reasons
    finally:
        node.close()


def _error_past_the_north_marker(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], **sensors: object
) -> tuple[float, int]:
    """|fused − true position| [m] 10 m past the north stop's marker (520 m), driving remotely at
    30 km/h on an SBAS-class GNSS (1 m of correlated error), and the markers read."""
    trackside, onboard = zenoh_pair
    noise = SensorNoise(gps_correlated_horizontal_sigma_m=1.0, gps_correlation_time_s=600.0)
    node = OnboardNode(
        OnboardSettings(
            vehicle_id="URV1",
            sensors=SensorSettings(seed=7, noise=noise, **sensors),  # type: ignore[arg-type]
        ),
        session=onboard,
        clock=SimClock(),
        track_map=RING,
    )
    try:
        node.track_database.record_trackside_version(
            m.LineVersionReply(line_id=RING.line.id, version=RING.version)
        )
        hands = LockstepOperator(trackside, node)
        assert wait_for(lambda: _reachable(hands))
        hands.run(3.0)
        assert hands.command(m.RemoteDrivingTargetCommand(target_speed_mps=30 / 3.6)).accepted
        marker = RING.line.stop_markers[0]
        assert marker.id == "north-marker"
        past = marker.position_m + 10.0
        assert hands.run_until(lambda: node.plant.position_m >= past, limit_s=150.0)
        reader = node.plant.marker_reader
        assert isinstance(reader, StopMarkerReader)
        error_m = abs(node.sensor_fusion.position_m - node.plant.position_m)
        hands.close()  # its trackside goes: the next node shakes hands with the next one's
        return error_m, reader.read
    finally:
        node.close()


def test_a_stop_marker_fixes_the_estimate_to_centimetres_before_the_stop(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    """With a GNSS a metre off, the estimate is as far off until the marker before the north
    stop; passing it, the marker reader's fix brings it within centimetres (issue 18: a stop
    within ±0.5 m needs a reference better than the GNSS's decimetres)."""
    with_marker, read = _error_past_the_north_marker(zenoh_pair)
    without, unread = _error_past_the_north_marker(
        zenoh_pair, missed_stop_markers=frozenset({"north-marker"})
    )
    assert (read, unread) == (1, 0)
    assert with_marker < 0.1
    assert without > 3.0 * with_marker
