"""The onboard node over real Zenoh sessions, in lockstep."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest
import zenoh

from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from protocol import LivelinessWatcher, TypedPublisher, TypedSubscriber, request
from protocol import messages as m
from protocol.registry import COMMAND, EVENT, STATUS, STATUS_ACK
from tests.conftest import wait_for
from tests.operator import LockstepOperator
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.scenario


@pytest.fixture
def node(zenoh_pair: tuple[zenoh.Session, zenoh.Session]) -> Iterator[OnboardNode]:
    _, onboard = zenoh_pair
    node = OnboardNode(
        OnboardSettings(vehicle_id="URV1"),
        session=onboard,
        clock=SimClock(),
        track_map=TrackMap(load_seed_line("bologna-ring")),
    )
    yield node
    node.close()


def _command(body: object, command_id: int = 1) -> m.Command:
    return m.Command(vehicle_id="URV1", command_id=command_id, issued_by="test", body=body)


def test_node_declares_liveliness_and_publishes_status(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], node: OnboardNode
) -> None:
    trackside, _ = zenoh_pair
    with (
        LivelinessWatcher(trackside, "ato/alive/ob/*") as watcher,
        TypedSubscriber(trackside, STATUS) as status,
    ):
        assert wait_for(lambda: watcher.alive() == {"ato/alive/ob/URV1"})

        # A new subscription takes some milliseconds to reach the publisher: run until the
        # first report arrives, then check each following second of lockstep time. Status is
        # latest-value (dropped under congestion), so a burst is checked a second at a time.
        def first_report_received() -> bool:
            node.run(0.2)
            return status.stats.received > 0

        assert wait_for(first_report_received)
        first = node.reports_sent
        for second in range(1, 11):
            node.run(1.0)
            assert node.reports_sent == first + 5 * second  # 5 Hz of simulated time
            assert wait_for(
                lambda: _seq(status.latest("ato/ob/URV1/status")) == node.reports_sent - 1
            ), (second, _seq(status.latest("ato/ob/URV1/status")), node.reports_sent, status.stats)
        end_s = node.clock.now_s
        latest = status.latest("ato/ob/URV1/status")
        assert latest is not None
        assert latest.sim_time_s == pytest.approx(end_s)
        # No trackside answers the track-data version: the ATO-OB stays in Configuration.
        assert latest.ato_state is m.AtoState.CONFIGURATION
        assert latest.speed_mps == 0.0


def test_remote_driving_command_moves_the_vehicle(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], node: OnboardNode
) -> None:
    trackside, _ = zenoh_pair
    events: list[m.Event] = []
    with TypedSubscriber(trackside, EVENT, on_message=lambda _k, e: events.append(e)):
        hands = LockstepOperator(trackside, node)
        ack = hands.command(m.RemoteDrivingTargetCommand(target_speed_mps=30 / 3.6))
        assert ack.accepted
        assert ack.command_id == hands.answers[-1].command_id
        hands.run(90.0)  # confirms the power-up EB rearm
        assert wait_for(lambda: any(e.code == "rd.target_speed" for e in events))
    report = node.status(node.clock.now_ns)
    assert report.sc_state is m.ScState.RD
    assert report.speed_mps == pytest.approx(30 / 3.6, abs=0.3)
    assert report.position_m > 300.0


def _seq(report: m.StatusReport | None) -> int:
    return -1 if report is None else report.seq


def test_a_command_outside_the_session_is_refused_and_counted(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], node: OnboardNode
) -> None:
    """Only the trackside the vehicle holds a session with commands it (issue 20): a bare
    command (no session id and number), one of another session and a replayed one are refused,
    the sealed one taken, once."""
    trackside, _ = zenoh_pair
    hands = LockstepOperator(trackside, node)
    target = m.RemoteDrivingTargetCommand(target_speed_mps=20 / 3.6)
    bare = request(trackside, COMMAND, _command(target, 1), vehicle="URV1")
    assert not bare.accepted
    assert bare.reason == "no session id and number"
    assert hands.bridge is not None
    seal = hands.bridge.seal("URV1")
    assert seal is not None
    sealed = _command(target, 2).model_copy(update={"freshness": seal})
    assert request(trackside, COMMAND, sealed, vehicle="URV1").accepted
    replayed = request(trackside, COMMAND, sealed, vehicle="URV1")
    assert not replayed.accepted
    assert replayed.reason is not None
    assert "replayed" in replayed.reason
    other = m.Freshness(session_id="not-this-session", number=seal.number + 1)
    forged = _command(target, 3).model_copy(update={"freshness": other})
    assert not request(trackside, COMMAND, forged, vehicle="URV1").accepted
    refused = node.session_client.guard.refused
    assert sum(refused.values()) == 3
    node.run(0.2)  # the refusals are logged at the next commands tick
    assert node.commands.rejected == 3


@pytest.mark.parametrize(
    ("body", "reason"),
    [
        (m.EngageCommand(), "no journey profile"),
        (m.DisengageCommand(), "not engaged"),
        (m.RemoteDrivingTargetCommand(target_speed_mps=50.0), "above line speed"),
    ],
)
def test_commands_that_cannot_be_obeyed_are_refused_with_a_reason(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], node: OnboardNode, body: object, reason: str
) -> None:
    trackside, _ = zenoh_pair
    ack = LockstepOperator(trackside, node).command(body)  # type: ignore[arg-type]
    assert not ack.accepted
    assert ack.reason is not None
    assert reason in ack.reason
    node.run(1.0)
    assert node.sc_state is m.ScState.OFF


def test_command_for_another_vehicle_is_refused(node: OnboardNode) -> None:
    command = m.Command(vehicle_id="URV2", command_id=1, issued_by="t", body=m.PingCommand())
    ack = node.commands.on_command({"vehicle": "URV1"}, command)
    assert not ack.accepted


def test_bogie_fidelity_drives_through_the_vcu(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    from onboard.plant.vehicle import BogiePlant

    trackside, onboard = zenoh_pair
    node = OnboardNode(
        OnboardSettings(vehicle_id="URV1", fidelity="bogie"),
        session=onboard,
        clock=SimClock(),
        track_map=TrackMap(load_seed_line("bologna-ring")),
    )
    try:
        assert isinstance(node.plant.dynamics, BogiePlant)
        assert node.vcu is not None
        hands = LockstepOperator(trackside, node)
        target = 30 / 3.6
        assert hands.command(m.RemoteDrivingTargetCommand(target_speed_mps=target)).accepted
        hands.run(60.0)
        assert node.plant.speed_mps == pytest.approx(target, abs=0.5)
        truth = node.plant.dynamics.truth
        wheel_speed = truth.wheel_speed_rear_radps * truth.wheel_radius_m
        assert wheel_speed == pytest.approx(truth.speed_mps, abs=0.1)  # rolling, no slip
    finally:
        node.close()


def test_the_lockstep_barrier_wakes_only_once_the_acknowledgement_can_be_taken(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], node: OnboardNode
) -> None:
    """The status barrier wakes on an STRAck; the session task then takes it from the queue. If
    the wake came first (seen with one subscriber to queue and another to wake, whose callbacks
    Zenoh ran apart), the report stayed unacknowledged and the session lapsed in a fault-free
    run. Each wake must find its acknowledgement already received."""
    trackside, _ = zenoh_pair
    received_at_wake: list[int] = []
    acks = node.ports.status_acks

    class Probe(threading.Event):
        def set(self) -> None:
            received_at_wake.append(acks.stats.received)
            super().set()

    node.barrier.acked = Probe()
    with TypedPublisher(trackside, STATUS_ACK, vehicle="URV1") as publisher:

        def first_wake_seen() -> bool:
            publisher.put(_ack(0))
            return bool(received_at_wake)

        assert wait_for(first_wake_seen)
        sent = len(received_at_wake)
        for seq in range(1, 51):
            publisher.put(_ack(seq))
        assert wait_for(lambda: len(received_at_wake) >= sent + 50)
    woken = list(received_at_wake)
    assert woken == list(range(1, len(woken) + 1))


def _ack(seq: int) -> m.StatusAck:
    return m.StatusAck(vehicle_id="URV1", seq=seq)
