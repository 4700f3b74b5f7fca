"""The node's closed loop on the fused localisation, and the localisation's health."""

from __future__ import annotations

import math

import zenoh

from onboard.ato_ob import Condition
from onboard.node import OnboardNode, OnboardSettings
from onboard.plant.sensors import SensorFaults, TimeWindow
from onboard.runtime import SimClock
from onboard.sfa.chain import SensorSettings
from protocol import messages as m
from tests.conftest import wait_for
from tests.operator import LockstepOperator
from trackdb import TrackMap, load_seed_line

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
