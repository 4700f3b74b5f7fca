"""The node's closed loop on the fused localisation, and on the truth when asked."""

from __future__ import annotations

import zenoh

from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from protocol import messages as m
from tests.conftest import wait_for
from tests.operator import LockstepOperator
from trackdb import TrackMap, load_seed_line

RING = TrackMap(load_seed_line("bologna-ring"))


def _drive(zenoh_pair: tuple[zenoh.Session, zenoh.Session], **settings: object) -> OnboardNode:
    trackside, onboard = zenoh_pair
    node = OnboardNode(OnboardSettings(vehicle_id="URV1", **settings),  # type: ignore[arg-type]
                       session=onboard, clock=SimClock(), track_map=RING)  # fmt: skip
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
        assert node.sensor_fusion is not None and node.sensor_fusion.estimate is not None
        stack, plant = node.stack, node.plant
        error_m = stack.position_m - plant.position_m
        assert error_m != 0.0 and abs(error_m) < 1.0
        assert stack.position_m == node.sensor_fusion.position_m
        assert abs(stack.speed_mps - plant.speed_mps) < 0.1
        status = node.status(node.clock.now_ns)
        assert status.position_m == RING.normalise(stack.position_m)
    finally:
        node.close()


def test_on_the_truth_the_node_runs_without_sensor_fusion(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    node = _drive(zenoh_pair, localisation="truth")
    try:
        assert node.sensor_fusion is None and "sfa" not in node.executive.tasks
        assert node.stack.position_m == node.plant.position_m > 100.0
    finally:
        node.close()
