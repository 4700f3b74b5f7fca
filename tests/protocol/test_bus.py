"""Typed pub/sub, query/reply and liveliness over real Zenoh sessions on loopback."""

from __future__ import annotations

import threading

import pytest
import zenoh
from hypothesis import given
from hypothesis import strategies as st

from protocol import (
    LivelinessWatcher,
    PayloadError,
    ProtocolError,
    RequestTimeoutError,
    TopicMonitor,
    TypedPublisher,
    TypedQueryable,
    TypedSubscriber,
    declare_liveliness,
    request,
    request_async,
)
from protocol import messages as m
from protocol.bus import RATE_WINDOW_S
from protocol.registry import COMMAND, EVENT, LINE_VERSION, STATUS
from tests.conftest import wait_for


def _status(seq: int, vehicle: str = "URV1") -> m.StatusReport:
    return m.StatusReport(
        vehicle_id=vehicle,
        seq=seq,
        sim_time_s=seq * 0.2,
        line_id="bologna-ring",
        position_m=float(seq),
        speed_mps=1.0,
        acceleration_mps2=0.0,
        traction_force_n=0.0,
        ato_state=m.AtoState.NOT_AVAILABLE,
        etcs_mode=m.EtcsMode.SR,
        sc_state=m.ScState.OFF,
    )


def test_pub_sub_between_two_sessions(zenoh_pair: tuple[zenoh.Session, zenoh.Session]) -> None:
    trackside, onboard = zenoh_pair
    with (
        TypedSubscriber(trackside, STATUS) as subscriber,
        TypedPublisher(onboard, STATUS, vehicle="URV1") as publisher,
    ):

        def first_status_received() -> bool:
            publisher.put(_status(0))
            return subscriber.stats.received > 0

        assert wait_for(first_status_received)
        publisher.put(_status(7))
        assert wait_for(lambda: (subscriber.latest("ato/ob/URV1/status") or _status(0)).seq == 7)
    assert subscriber.stats.bad_payloads == 0


def test_fifo_keeps_every_message_in_order(zenoh_pair: tuple[zenoh.Session, zenoh.Session]) -> None:
    trackside, onboard = zenoh_pair
    received: list[int] = []
    with (
        TypedSubscriber(trackside, EVENT, on_message=lambda _k, e: received.append(e.seq)),
        TypedPublisher(onboard, EVENT, vehicle="URV1") as publisher,
    ):
        ping = m.Event(
            vehicle_id="URV1", seq=10**6, sim_time_s=0, severity="info", code="x", text=""
        )

        def ping_received() -> bool:
            publisher.put(ping)
            return bool(received)

        assert wait_for(ping_received)
        received.clear()
        for seq in range(200):
            publisher.put(
                m.Event(
                    vehicle_id="URV1", seq=seq, sim_time_s=0, severity="info", code="x", text=""
                )
            )
        assert wait_for(lambda: len([s for s in received if s < 10**6]) == 200)
    assert [s for s in received if s < 10**6] == list(range(200))


def test_bad_payloads_are_counted_not_raised(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    trackside, onboard = zenoh_pair
    with TypedSubscriber(trackside, STATUS) as subscriber:
        for payload in (b"garbage", b'{"vehicle_id": "URV1"}', b"\xff" * 10):

            def bad_payload_counted(p: bytes = payload) -> bool:
                onboard.put("ato/ob/URV1/status", p)
                return subscriber.stats.bad_payloads > 0

            assert wait_for(bad_payload_counted)
        onboard.put("ato/ob/URV1/status", STATUS.encode(_status(3)))
        assert wait_for(lambda: subscriber.stats.received == 1)
        assert subscriber.stats.last_error is not None


def test_a_drained_subscriber_takes_every_sample_in_batches_on_its_own_thread(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    trackside, onboard = zenoh_pair
    received: list[tuple[int, str]] = []
    period_s = 0.05

    def on_message(_key: str, report: m.StatusReport) -> None:
        received.append((report.seq, threading.current_thread().name))

    subscriber = TypedSubscriber(trackside, STATUS, on_message=on_message, drain_period_s=period_s)
    with TypedPublisher(onboard, STATUS, vehicle="URV1") as publisher:

        def first_received() -> bool:
            publisher.put(_status(10**6))
            return bool(received)

        assert wait_for(first_received)
        received.clear()
        for seq in range(300):
            publisher.put(_status(seq))
        assert wait_for(lambda: len([s for s, _ in received if s < 10**6]) == 300)
        onboard.put("ato/ob/URV1/status", b"garbage")
        assert wait_for(lambda: subscriber.stats.bad_payloads == 1)
    subscriber.close()
    assert [s for s, _ in received if s < 10**6] == list(range(300))
    assert {name for _, name in received} == {"status-intake"}
    assert subscriber.stats.queue_overflows == 0
    drainer = subscriber._drainer
    assert drainer is not None
    assert not drainer.is_alive()  # the ring closed with the subscriber
    latest = subscriber.latest("ato/ob/URV1/status")
    assert latest is not None
    assert latest.seq == 299


def test_a_drained_subscriber_counts_a_ring_overrun(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    """More samples in a period than the ring holds: the oldest are lost, and counted."""
    trackside, onboard = zenoh_pair
    subscriber = TypedSubscriber(trackside, STATUS, drain_period_s=0.5, ring_capacity=8)
    with subscriber, TypedPublisher(onboard, STATUS, vehicle="URV1") as publisher:
        sent = [0]

        def overrun() -> bool:
            for seq in range(200):
                publisher.put(_status(seq))
            sent[0] += 200
            return subscriber.stats.queue_overflows > 0

        assert wait_for(overrun, timeout_s=10.0)
        assert subscriber.stats.received < sent[0]  # lost in the ring, not queued without end


def test_query_reply(zenoh_pair: tuple[zenoh.Session, zenoh.Session]) -> None:
    trackside, onboard = zenoh_pair

    def answer(chunks: dict[str, str], command: m.Command) -> m.CommandAck:
        return m.CommandAck(
            vehicle_id=chunks["vehicle"],
            command_id=command.command_id,
            accepted=True,
            sim_time_s=1.5,
        )

    command = m.Command(vehicle_id="URV1", command_id=41, issued_by="t", body=m.PingCommand())
    with TypedQueryable(onboard, COMMAND, answer, vehicle="URV1") as queryable:
        assert wait_for(lambda: _try_request(trackside, command) is not None)
        ack = request(trackside, COMMAND, command, vehicle="URV1")
        assert ack == m.CommandAck(vehicle_id="URV1", command_id=41, accepted=True, sim_time_s=1.5)
        # A malformed request gets an error reply, counted by the queryable.
        replies = list(trackside.get("ato/ob/URV1/command", payload=b"{}", timeout=2.0))
        assert replies
        assert replies[0].err is not None
        assert queryable.stats.bad_payloads == 1


def _try_request(session: zenoh.Session, command: m.Command) -> m.CommandAck | None:
    try:
        ack: m.CommandAck = request(session, COMMAND, command, timeout_s=0.2, vehicle="URV1")
    except (RequestTimeoutError, PayloadError):
        return None
    return ack


def test_request_async_hands_the_reply_model_to_its_callback(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    trackside, onboard = zenoh_pair
    replies: list[m.CommandAck] = []

    def answer(_chunks: dict[str, str], command: m.Command) -> m.CommandAck:
        return m.CommandAck(
            vehicle_id="URV1", command_id=command.command_id, accepted=False, sim_time_s=0.0
        )

    command = m.Command(vehicle_id="URV1", command_id=5, issued_by="t", body=m.PingCommand())
    with TypedQueryable(onboard, COMMAND, answer, vehicle="URV1"):
        assert wait_for(lambda: _try_request(trackside, command) is not None)
        request_async(trackside, COMMAND, command, replies.append, vehicle="URV1")
        assert wait_for(lambda: bool(replies))
    assert isinstance(replies[0], m.CommandAck)
    assert replies[0].command_id == 5


def test_a_reply_that_does_not_validate_raises_payload_error(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    trackside, onboard = zenoh_pair
    # A replier outside the registry's helpers, answering a command with a line version.
    wrong = LINE_VERSION.encode_reply(m.LineVersionReply(line_id="bologna-ring", version="1"))
    queryable = onboard.declare_queryable(
        COMMAND.key(vehicle="URV3"), lambda query: query.reply(query.key_expr, wrong)
    )
    command = m.Command(vehicle_id="URV3", command_id=1, issued_by="t", body=m.PingCommand())
    async_replies: list[m.CommandAck] = []
    try:
        assert wait_for(lambda: _refused(trackside, command))
        with pytest.raises(PayloadError, match="command reply"):
            request(trackside, COMMAND, command, timeout_s=1.0, vehicle="URV3")
        request_async(trackside, COMMAND, command, async_replies.append, vehicle="URV3")
        # A second query behind it on the same link: once its reply is in, so is the first's.
        done = threading.Event()
        trackside.get(COMMAND.key(vehicle="URV3"), lambda _r: done.set(), timeout=1.0)
        assert done.wait(2.0)
    finally:
        queryable.undeclare()
    assert async_replies == []  # dropped and logged, as a receiver does


def _refused(session: zenoh.Session, command: m.Command) -> bool:
    try:
        request(session, COMMAND, command, timeout_s=0.2, vehicle="URV3")
    except RequestTimeoutError:
        return False
    except PayloadError:
        return True
    return False


def test_query_helpers_refuse_the_wrong_kind_of_topic(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    trackside, _ = zenoh_pair
    with pytest.raises(ProtocolError, match="is a query topic"):
        TypedPublisher(trackside, COMMAND, vehicle="URV1")
    with pytest.raises(ProtocolError, match="not a query topic"):
        TypedQueryable(trackside, STATUS, lambda _c, _s: None)  # type: ignore[arg-type]


def test_request_without_replier_times_out(zenoh_pair: tuple[zenoh.Session, zenoh.Session]) -> None:
    trackside, _ = zenoh_pair
    command = m.Command(vehicle_id="NOBODY", command_id=0, issued_by="t", body=m.PingCommand())
    with pytest.raises(RequestTimeoutError):
        request(trackside, COMMAND, command, timeout_s=0.3, vehicle="NOBODY")


def test_liveliness_appears_and_disappears(zenoh_pair: tuple[zenoh.Session, zenoh.Session]) -> None:
    trackside, onboard = zenoh_pair
    changes: list[tuple[str, bool]] = []
    seen = threading.Event()

    def on_change(key: str, up: bool) -> None:
        changes.append((key, up))
        seen.set()

    with LivelinessWatcher(trackside, "ato/alive/ob/*", on_change) as watcher:
        token = declare_liveliness(onboard, "ato/alive/ob/URV9")
        assert wait_for(lambda: watcher.alive() == {"ato/alive/ob/URV9"})
        token.undeclare()
        assert wait_for(lambda: watcher.alive() == set())
    assert changes == [("ato/alive/ob/URV9", True), ("ato/alive/ob/URV9", False)]


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_monitor_alive_and_rate() -> None:
    clock = FakeClock()
    monitor = TopicMonitor(5.0, clock)
    key = "ato/ob/URV1/status"
    assert not monitor.alive(key)
    for _ in range(26):
        monitor.record(key)
        clock.now += 0.2
    assert monitor.alive(key)
    assert monitor.rate_hz(key) == pytest.approx(5.0)
    assert monitor.rate_ok(key)
    clock.now += 0.2  # 0.4 s since the last: within 2.5 periods (0.5 s)
    assert monitor.alive(key)
    clock.now += 0.2
    assert not monitor.alive(key)
    assert not monitor.rate_ok(key)


def test_monitor_rate_counts_the_window_before_now_only() -> None:
    """Arrivals kept (a window behind the last) but older than a window before now are left
    out of the rate, as if counted one by one."""
    clock = FakeClock()
    monitor = TopicMonitor(5.0, clock)
    stamps = []
    for index in range(40):
        stamps.append(clock.now)
        monitor.record("k")
        clock.now += 0.2 if index < 30 else 0.5
    for quiet_s in (0.0, 1.3, 4.0, 5.2):
        now = stamps[-1] + quiet_s
        recent = [t for t in stamps if now - t <= RATE_WINDOW_S]
        expected = (len(recent) - 1) / (recent[-1] - recent[0]) if len(recent) > 1 else 0.0
        assert monitor.rate_hz("k", now) == pytest.approx(expected, rel=1e-12)
    assert monitor.rate_hz("k", stamps[-1] + 5.2) == 0.0  # the last alone in the window


def test_monitor_flags_a_slow_publisher() -> None:
    clock = FakeClock()
    monitor = TopicMonitor(5.0, clock)
    for _ in range(10):
        monitor.record("k")
        clock.now += 0.4  # 2.5 Hz, still within the alive window
    clock.now -= 0.3
    assert monitor.alive("k")
    assert not monitor.rate_ok("k")


@given(
    gaps=st.lists(st.lists(st.floats(0.05, 1.5), min_size=1, max_size=40), min_size=1, max_size=6),
    quiet_s=st.floats(0.0, 6.0),
    rate_hz=st.sampled_from([None, 5.0]),
)
def test_the_monitor_s_health_is_each_key_s_last_arrival_and_rate(
    gaps: list[list[float]], quiet_s: float, rate_hz: float | None
) -> None:
    """The fleet's list reads every key's health in one pass: the same as asking key by key."""
    clock = FakeClock()
    monitor = TopicMonitor(rate_hz, clock)
    for index, key_gaps in enumerate(gaps):
        clock.now = 0.0
        for gap in key_gaps:
            clock.now += gap
            monitor.record(f"k{index}")
    now = max(sum(key_gaps) for key_gaps in gaps) + quiet_s
    health = monitor.health(now)
    assert set(health) == {f"k{index}" for index in range(len(gaps))}
    for key, (last, ok) in health.items():
        assert last == monitor.last_seen(key)
        assert ok == monitor.rate_ok(key, now)
