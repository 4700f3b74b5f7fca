"""The Vital Control fitted to the onboard node: its ATO-OB link, the operator relay, the EB on
the plant, the ETCS relay, the BTM, 2oo2 and the datalog, over real Zenoh commands, in
lockstep."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest
import zenoh

from onboard.node import NODE_VC_CONFIG, OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from onboard.vc import read_datalog
from protocol import TypedSubscriber
from protocol import messages as m
from protocol.registry import EVENT
from tests.conftest import wait_for
from tests.operator import LockstepOperator
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.scenario

RING = TrackMap(load_seed_line("bologna-ring"))
KMH = 1 / 3.6


def _node(onboard: zenoh.Session, **settings: object) -> OnboardNode:
    return OnboardNode(
        OnboardSettings(vehicle_id="URV1", **settings),  # type: ignore[arg-type]
        session=onboard,
        clock=SimClock(),
        track_map=RING,
    )


@pytest.fixture
def events(zenoh_pair: tuple[zenoh.Session, zenoh.Session]) -> Iterator[list[m.Event]]:
    received: list[m.Event] = []
    with TypedSubscriber(zenoh_pair[0], EVENT, on_message=lambda _k, e: received.append(e)):
        yield received


@pytest.fixture
def hands(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], events: list[m.Event]
) -> Iterator[LockstepOperator]:
    del events  # subscribed before the node starts, so that no event is missed
    trackside, onboard = zenoh_pair
    node = _node(onboard)
    hands = LockstepOperator(trackside, node)
    assert wait_for(lambda: _reachable(hands))
    yield hands
    node.close()


def _reachable(hands: LockstepOperator) -> bool:
    try:
        return hands.command(m.PingCommand()).accepted
    except Exception:
        return False


def _vital(node: OnboardNode) -> m.VitalControlStatus:
    status = node.status(node.clock.now_ns).vital_control
    assert status is not None
    return status


def _pending(node: OnboardNode, kind: m.OperatorRequestKind) -> m.OperatorRequest | None:
    return next((r for r in _vital(node).operator_requests if r.kind is kind), None)


def _seen(events: list[m.Event], code: str) -> bool:
    return wait_for(lambda: any(event.code == code for event in events))


def _drive(hands: LockstepOperator, speed_kmh: float) -> None:
    body = m.RemoteDrivingTargetCommand(target_speed_mps=speed_kmh * KMH)
    assert hands.command(body).accepted


def test_power_up_holds_the_eb_until_the_operator_confirms_the_rearm(
    hands: LockstepOperator,
) -> None:
    node = hands.node
    hands.present = False
    node.run(1.0)
    vital = _vital(node)
    assert vital.eb_commanded
    assert vital.brake_state == "standstill"
    rearm = _pending(node, m.OperatorRequestKind.EB_REARM)
    vigilance = _pending(node, m.OperatorRequestKind.VIGILANCE)
    assert rearm is not None
    assert not rearm.confirmed
    assert vigilance is not None
    assert vigilance.deadline_s == pytest.approx(10.0)
    answer = m.OperatorConfirmCommand(request=vigilance.kind, number=vigilance.number)
    assert hands.command(answer).accepted
    # The EB from another source keeps the ATO-OB from being available.
    assert node.stack.controller.state is not m.AtoState.AVAILABLE
    _drive(hands, 20.0)
    node.run(5.0)
    assert node.plant.speed_mps == 0.0
    # A late or wrong answer is refused with the reason, a right one is taken.
    wrong = hands.command(m.OperatorConfirmCommand(request=rearm.kind, number=rearm.number + 1))
    assert not wrong.accepted
    assert "not the pending one" in (wrong.reason or "")
    assert hands.command(m.OperatorConfirmCommand(request=rearm.kind, number=rearm.number)).accepted
    node.run(5.0)
    assert _vital(node).brake_state == "released"
    assert not _vital(node).eb_commanded
    assert node.plant.speed_mps > 1.0  # the target set while braked applies after the rearm


def test_operator_emergency_brake_stops_the_train_and_needs_a_rearm(
    hands: LockstepOperator, events: list[m.Event]
) -> None:
    node = hands.node
    _drive(hands, 30.0)
    hands.run(40.0)
    assert node.plant.speed_mps == pytest.approx(30 * KMH, abs=0.5)
    assert hands.command(m.EmergencyBrakeCommand()).accepted
    hands.present = False  # the operator does not rearm yet
    node.run(0.5)
    vital = _vital(node)
    assert vital.eb_commanded
    assert vital.brake_state == "braking"
    assert 1 in vital.eb_conditions
    assert _seen(events, "vc.eb_commanded")
    node.run(15.0)  # 8.3 m/s at about 0.93 m/s²: 9 s and the 450 ms pipe
    assert node.plant.speed_mps == 0.0
    assert _pending(node, m.OperatorRequestKind.EB_REARM) is not None
    assert node.stack.remote_target_mps == 0.0  # no restart by itself after the rearm
    hands.present = True
    hands.run(3.0)
    assert not _vital(node).eb_commanded
    assert not _vital(node).system_decay
    assert node.plant.speed_mps == 0.0
    _drive(hands, 20.0)
    hands.run(10.0)
    assert node.plant.speed_mps > 3.0


def test_unanswered_vigilance_brakes_and_decays(hands: LockstepOperator) -> None:
    node = hands.node
    _drive(hands, 30.0)
    hands.run(25.0)  # the power-up vigilance and rearm answered
    hands.present = False  # the next request comes at 30 s and is not answered
    node.run(16.0)
    vital = _vital(node)
    assert vital.system_decay
    assert "vigilance_timeout" in vital.decay_reasons
    assert vital.eb_commanded
    node.run(15.0)
    assert node.plant.speed_mps == 0.0
    # In System Decay nothing is asked of the operator but vitality: the train stays stopped.
    hands.present = True
    hands.run(5.0)
    assert _vital(node).eb_commanded
    assert node.plant.speed_mps == 0.0


def test_etcs_isolation_then_overspeed_above_30_kmh_brakes_then_insertion(
    hands: LockstepOperator, events: list[m.Event]
) -> None:
    node = hands.node
    etcs = node.stack.etcs
    hands.run(2.0)
    assert etcs.mode is m.EtcsMode.SR
    isolation = _pending(node, m.OperatorRequestKind.ETCS_ISOLATION)
    assert isolation is not None
    confirm = m.OperatorConfirmCommand(request=isolation.kind, number=isolation.number)
    assert hands.command(confirm).accepted
    hands.run(1.0)
    assert etcs.mode is m.EtcsMode.IS
    assert _vital(node).etcs_isolated
    assert _seen(events, "vc.etcs_isolated")
    # With ETCS isolated the VC supervises 30 km/h itself (condition 6, scenario L).
    _drive(hands, 28.0)
    hands.run(40.0)
    assert not _vital(node).eb_commanded
    _drive(hands, 40.0)
    assert hands.run_until(lambda: _vital(node).eb_commanded, 20.0, slice_s=0.1)
    assert 6 in _vital(node).eb_conditions
    assert node.plant.speed_mps < 31 * KMH
    assert hands.run_until(lambda: node.plant.speed_mps == 0.0, 20.0)
    hands.run(3.0)  # rearmed at standstill, the hazard gone
    assert not _vital(node).eb_commanded
    insertion = _pending(node, m.OperatorRequestKind.ETCS_INSERTION)
    assert insertion is not None
    assert hands.command(
        m.OperatorConfirmCommand(request=insertion.kind, number=insertion.number)
    ).accepted
    hands.run(1.0)
    assert not _vital(node).etcs_isolated
    assert etcs.mode is m.EtcsMode.SR  # inserted, then started in Staff Responsible again


def test_the_vc_forwards_balise_headers_read_by_etcs(hands: LockstepOperator) -> None:
    node = hands.node
    _drive(hands, 30.0)
    assert hands.run_until(lambda: node.stack.etcs.mode is m.EtcsMode.FS, 60.0)
    hands.run(0.2)
    request = node.stack.vital_links[0].last_request
    assert request is not None
    assert request.last_balise_header is not None
    first_group = RING.line.balise_groups[0]
    assert request.last_balise_header.nid_bg == first_group.id


def test_ato_ob_failure_status_brakes_and_decays(hands: LockstepOperator) -> None:
    node = hands.node
    _drive(hands, 20.0)
    hands.run(20.0)
    for link in node.stack.vital_links:
        link.reports_failure = True  # injected: the ATO-OB reports FAIL (scenario B)
    hands.run(0.1)
    vital = _vital(node)
    assert vital.eb_commanded
    assert vital.system_decay
    assert "ato_ob_fail" in vital.decay_reasons


def test_two_vc_boards_in_2oo2_run_and_brake_together(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], events: list[m.Event], tmp_path: Path
) -> None:
    trackside, onboard = zenoh_pair
    datalog = tmp_path / "vc.jsonl"
    node = _node(onboard, vc_replicas=2, vc_datalog=datalog)
    try:
        hands = LockstepOperator(trackside, node)
        assert wait_for(lambda: _reachable(hands))
        _drive(hands, 30.0)
        hands.run(30.0)
        vital = _vital(node)
        assert vital.replicas == 2
        assert not vital.pair_tripped
        assert not vital.eb_commanded
        assert node.plant.speed_mps == pytest.approx(30 * KMH, abs=0.5)
        assert hands.command(m.EmergencyBrakeCommand()).accepted
        hands.run(12.0)
        assert node.plant.speed_mps == 0.0
        assert not _vital(node).pair_tripped  # both boards braked alike
        assert _seen(events, "vc.pair.replica_eb")
    finally:
        node.close()
    replay = read_datalog(datalog)
    kinds = {record.kind for record in replay.records}
    assert {"eb_commanded", "eb_rearmed", "notifications", "replica_eb"} <= kinds


def test_lockstep_runs_with_the_vc_are_identical(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    trackside, onboard = zenoh_pair

    def run() -> list[tuple[float, float, str, bool]]:
        node = _node(onboard)
        # Each run's trackside bridge is closed with it: a bridge left over from the first run
        # would answer the second node's session request too, with a session of its own.
        hands = LockstepOperator(trackside, node)
        try:
            assert wait_for(lambda: _reachable(hands))
            _drive(hands, 30.0)
            trace = []
            for _ in range(40):
                hands.run(0.5)
                vital = _vital(node)
                trace.append(
                    (
                        node.plant.position_m,
                        node.plant.speed_mps,
                        vital.brake_state,
                        vital.eb_commanded,
                    )
                )
            return trace
        finally:
            hands.close()
            node.close()

    assert run() == run()


def test_with_fused_speed_supervision_the_vc_brakes_at_30_kmh_on_the_fused_speed(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    trackside, onboard = zenoh_pair
    config = replace(NODE_VC_CONFIG, fused_speed_supervision=True)
    node = _node(onboard, vc_config=config)
    try:
        hands = LockstepOperator(trackside, node)
        assert wait_for(lambda: _reachable(hands))
        hands.run(2.0)
        isolation = _pending(node, m.OperatorRequestKind.ETCS_ISOLATION)
        assert isolation is not None
        assert hands.command(
            m.OperatorConfirmCommand(request=isolation.kind, number=isolation.number)
        ).accepted
        hands.run(1.0)
        _drive(hands, 40.0)
        assert hands.run_until(lambda: _vital(node).eb_commanded, 30.0, slice_s=0.02)
        assert 6 in _vital(node).eb_conditions
        # The fused speed arrives every 10 ms, the tachometer's every 80 ms: the EB comes
        # before the train is far above the limit.
        assert node.plant.speed_mps < 30.5 * KMH
    finally:
        node.close()
