"""The listener core: validation counted by reason, epochs from STROBE, reordering, ACK link,
STOP, and fuzzing with every datagram accounted for."""

from __future__ import annotations

import socket
import struct
import threading
from collections.abc import Callable

import numpy as np
import pytest

from deploy.bench.sfa_bench import fuzz_datagrams, fuzz_listener
from onboard.sfa import Health, ListenerConfig, ListenerCore, SensorTimeBase
from onboard.sfa.sockets import ListenerRunner
from protocol.udp import InputPacket, SensorType, decode_output, encode_ack, encode_input
from tests.conftest import wait_for
from trackdb import TrackMap, load_seed_line

IMU_LEVEL = (0.0, 0.0, -9.81, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line("bologna-ring"))


def packet(sensor_type: SensorType, seq: int, *doubles: float) -> bytes:
    return encode_input(InputPacket(sensor_type, seq % 65536, tuple(doubles)))


def test_malformed_datagrams_are_dropped_and_counted_by_reason(ring: TrackMap) -> None:
    core = ListenerCore(ring)
    good = packet(SensorType.IMU, 0, *IMU_LEVEL)
    nan = bytearray(good)
    nan[5:13] = struct.pack("<d", float("nan"))
    bad = [
        b"\x01\x00",  # truncated
        good[:-1],  # length mismatch
        bytes([7, 0, 0, 0, 0]),  # unknown type
        bytes([1, 0, 0, 0, 1]) + struct.pack("<d", 1.0),  # IMU with one double
        bytes(nan),  # non-finite
        packet(SensorType.IMU, 1, 500.0, 0, 0, 0, 0, 0),  # implausible
    ]
    for datagram in bad:
        assert core.feed(datagram, 0.0) == []
    assert dict(core.counters.dropped) == {
        "truncated": 1,
        "length_mismatch": 1,
        "unknown_type": 1,
        "count_mismatch": 1,
        "non_finite": 1,
        "invalid_value": 1,
    }
    assert core.counters.accounted(len(core.buffer)) == core.counters.received == 6


def test_sensor_packets_before_ground_truth_are_ignored_then_it_initialises(
    ring: TrackMap,
) -> None:
    core = ListenerCore(ring)
    core.feed(packet(SensorType.IMU, 0, *IMU_LEVEL), 0.0)
    assert core.counters.before_ground_truth == 1
    assert core.status is None
    outputs = core.feed(packet(SensorType.GROUND_TRUTH, 1, 5.0, 0.0, 0.0, 1.5), 0.0)
    assert core.status is not None
    assert core.status.chainage_m == pytest.approx(1500.0)
    assert core.status.speed_mps == pytest.approx(5.0)
    assert [decode_output(o).seq_no for o in outputs] == [0]


def test_epochs_are_the_strobe_plus_k_over_the_rate(ring: TrackMap) -> None:
    core = ListenerCore(ring)
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0), 0.0)
    core.feed(packet(SensorType.STROBE, 1, 50.0), 0.0)
    for seq in range(2, 6):
        core.feed(packet(SensorType.IMU, seq, *IMU_LEVEL), 0.0)
    assert core.filter.epoch_s == pytest.approx(50.03)
    core.feed(packet(SensorType.ODOMETER, 6, 0.0, 0.05), 0.0)
    assert core.filter.epoch_s == pytest.approx(50.03)  # odometer k = 0: 50.00, not ahead
    core.feed(packet(SensorType.STROBE, 7, 51.0), 0.0)
    core.feed(packet(SensorType.IMU, 8, *IMU_LEVEL), 0.0)
    assert core.filter.epoch_s == pytest.approx(51.0)


def test_the_time_base_counts_epochs_and_holds_a_strobe_off_schedule_until_confirmed() -> None:
    time_base = SensorTimeBase(imu_rate_hz=100.0, odometer_rate_hz=20.0, gps_rate_hz=1.0)
    assert time_base.packets_per_s == 122.0
    assert time_base.strobe(50.0, 1) is None  # the first after start sets the base
    imu_epochs = [time_base.epoch(SensorType.IMU, seq) for seq in (2, 3)]
    assert imu_epochs == pytest.approx([50.0, 50.01])
    # 122 SEQ_NO on (one second of packets) it should read 51 s: held back.
    assert time_base.strobe(51.5, 123) == "strobe_unconfirmed"
    assert time_base.strobe(2_000.0, 200) == "invalid_value"  # beyond 600 s ahead
    # The next second on the schedule of the held one confirms it.
    assert time_base.strobe(52.5, 245) is None
    assert time_base.epoch(SensorType.ODOMETER, 246) == 52.5
    time_base.rebase()  # a GROUND_TRUTH: the next STROBE is taken whatever its time
    assert time_base.strobe(0.0, 300) is None
    assert time_base.strobe_s == 0.0


def test_a_gps_fix_whose_strobe_and_last_fix_were_lost_keeps_its_own_second() -> None:
    """gen-1-493 at 96 s: the GPS fix of one second and the STROBE of the next both lost, the
    next fix counted as the first since the older STROBE read a second early (the SEQ_NO bound
    cannot tell one second from the next at 1 Hz); taken as the position of 0.8 s before at
    5 m/s, it pulled the estimate 2 m off with the odometer failed."""
    time_base = SensorTimeBase(imu_rate_hz=100.0, odometer_rate_hz=20.0, gps_rate_hz=1.0)
    assert time_base.strobe(96.0, 1) is None
    # The GPS of 96 s (SEQ_NO 2) is lost; one IMU packet in six too.
    imu_epochs = [time_base.epoch(SensorType.IMU, 3 + tick) for tick in range(100) if tick % 6 != 5]
    assert imu_epochs[-1] <= 96.99 + 1e-9  # never ahead of the packet's own time
    # The STROBE of 97 s (SEQ_NO 103) is lost: the GPS of 97 s comes next.
    assert time_base.epoch(SensorType.GPS, 104) == pytest.approx(97.0)
    # The IMU after it is pulled up too, to within the order's tolerance (0.05 s).
    assert time_base.epoch(SensorType.IMU, 105) >= 96.95 - 1e-9
    # A packet just after a STROBE keeps its count: the bound is no more than the order.
    assert time_base.strobe(98.0, 205) is None
    assert time_base.epoch(SensorType.GPS, 206) == 98.0
    assert time_base.epoch(SensorType.ODOMETER, 207) == 98.0


def test_under_loss_the_sequence_distance_keeps_the_epoch_from_lagging(ring: TrackMap) -> None:
    core = ListenerCore(ring, ListenerConfig(reorder_max_wait_s=0.0))
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0), 0.0)
    core.feed(packet(SensorType.STROBE, 1, 10.0), 0.0)
    # 200 SEQ_NO later (at most 122 packets a second): at least 1.6 s of IMU ticks have passed.
    # The first packet out of the reorder window is refused, the next one confirms the jump.
    core.feed(packet(SensorType.IMU, 201, *IMU_LEVEL), 1.0)
    core.feed(packet(SensorType.IMU, 202, *IMU_LEVEL), 1.0)
    assert core.counters.dropped == {"out_of_window": 1}
    assert core.filter.epoch_s >= 11.6
    assert core.buffer.lost == 200


def test_a_corrupted_seq_no_far_ahead_is_dropped_and_moves_nothing(ring: TrackMap) -> None:
    core = ListenerCore(ring)
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0), 0.0)
    core.feed(packet(SensorType.STROBE, 1, 10.0), 0.0)
    core.feed(packet(SensorType.IMU, 2, *IMU_LEVEL), 0.0)
    corrupted = packet(SensorType.IMU, 2 + 12421, *IMU_LEVEL)  # one SEQ_NO byte flipped
    core.feed(corrupted, 0.01)
    core.feed(corrupted, 0.02)  # and duplicated by the link
    for seq in range(3, 40):
        core.feed(packet(SensorType.IMU, seq, *IMU_LEVEL), 0.01 * seq)
    core.poll(1.0)
    assert core.counters.dropped == {"out_of_window": 2}
    assert core.counters.processed["imu"] == 38
    assert core.buffer.lost == 0
    assert core.filter.epoch_s == pytest.approx(10.37)


def one_second(seq: int, strobe_s: float, *, strobe: bool = True) -> list[bytes]:
    """A second of the sender's packets from ``seq`` on: its STROBE (unless lost), then 100
    IMU and 20 odometer packets interleaved as the interface-modules send them (no GPS)."""
    stream = [packet(SensorType.STROBE, seq, strobe_s)] if strobe else []
    for tick in range(100):
        stream.append(packet(SensorType.IMU, seq + len(stream) + (not strobe), *IMU_LEVEL))
        if tick % 5 == 0:
            stream.append(packet(SensorType.ODOMETER, seq + len(stream) + (not strobe), 0.0, 0.05))
    return stream


def feed_seconds(core: ListenerCore, seconds: list[tuple[float, float, bool]]) -> list[float]:
    """Feed whole seconds (their sender time, the STROBE's time, whether it arrives), the
    first from SEQ_NO 1 after a GROUND_TRUTH; returns the filter's epoch after each."""
    epochs = []
    for second_s, strobe_s, arrives in seconds:
        seq = 1 + 121 * round(second_s - seconds[0][0])
        for index, datagram in enumerate(one_second(seq, strobe_s, strobe=arrives)):
            core.feed(datagram, second_s + 0.008 * index)
        epochs.append(core.filter.epoch_s)
    return epochs


def test_a_strobe_off_schedule_is_dropped_until_the_next_strobe_confirms_it(
    ring: TrackMap,
) -> None:
    """A STROBE's time corrupted 0.84 s forwards (one mantissa byte; gen-1-26 at 54 s) moved
    every epoch of its second ahead: the filter predicted 0.84 s with the last acceleration and
    the odometer was gated out for good. Off its schedule (a whole number of seconds after the
    last STROBE, as many as its SEQ_NO distance spans) it is now dropped, the epochs run on
    from the last STROBE, and the next STROBE on schedule is taken (after a lost one too)."""
    core = ListenerCore(ring)
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0), 0.0)
    epochs = feed_seconds(
        core,
        [
            (10.0, 10.0, True),
            (11.0, 11.84375, True),
            (12.0, 12.0, True),
            (13.0, 13.0, False),
            (14.0, 14.0, True),
            # The sender's clock steps: followed from its second STROBE.
            (15.0, 500.0, True),
            (16.0, 501.0, True),
        ],
    )
    assert epochs == pytest.approx([10.99, 11.99, 12.99, 13.99, 14.99, 15.99, 501.99], abs=0.015)
    assert core.counters.dropped == {"strobe_unconfirmed": 2}
    assert core.counters.processed["strobe"] == 4


def test_a_seq_no_corrupted_ahead_within_the_window_is_misplaced_not_processed(
    ring: TrackMap,
) -> None:
    """An IMU packet's SEQ_NO read 26 numbers ahead (one byte): processed in that place it
    would have been a sample 0.2 s old, or, across a STROBE, one count too many for the rest
    of the second. It waits for its turn and is refused: it arrived 0.2 s before the packets
    ahead of it in the sequence, more than the reorder buffer waits for anything."""
    core = ListenerCore(ring)
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0), 0.0)
    stream = one_second(1, 10.0)
    corrupted = bytearray(stream[40])
    assert corrupted[0] == SensorType.IMU
    corrupted[1] += 26  # the SEQ_NO's low byte
    stream[40] = bytes(corrupted)
    for index, datagram in enumerate(stream):
        core.feed(datagram, 10.0 + 0.008 * index)
    core.poll(12.0)
    assert core.counters.dropped == {"misplaced": 1}
    assert core.counters.processed["imu"] == 99
    assert core.buffer.lost == 1
    assert core.counters.accounted(len(core.buffer)) == core.counters.received
    assert core.filter.epoch_s == pytest.approx(10.98)  # one IMU short, as for any loss


def test_reordered_packets_are_processed_in_order(ring: TrackMap) -> None:
    core = ListenerCore(ring)
    stream = [packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0)]
    stream += [packet(SensorType.IMU, seq, *IMU_LEVEL) for seq in range(1, 9)]
    shuffled = [stream[i] for i in (0, 2, 1, 4, 3, 8, 5, 7, 6)]
    for datagram in shuffled:
        core.feed(datagram, 0.0)
    assert core.counters.processed["imu"] == 8
    assert not core.counters.dropped
    assert core.filter.epoch_s == pytest.approx(0.07)


def test_obcu_link_is_lost_after_three_seconds_without_ack(ring: TrackMap) -> None:
    core = ListenerCore(ring)
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0), 10.0)
    assert not core.link_lost(12.9)
    assert core.link_lost(13.1)
    core.on_ack(encode_ack_seq(0), 13.2)
    assert not core.link_lost(16.1)
    assert core.link_lost(16.3)
    core.on_ack(b"\x00", 16.4)
    assert core.counters.acks_malformed == 1
    assert core.last_ack_seq == 0


def encode_ack_seq(seq: int) -> bytes:
    from protocol.udp import Ack

    return encode_ack(Ack(seq))


def test_stop_ends_the_listener_and_what_follows_is_counted(ring: TrackMap) -> None:
    core = ListenerCore(ring)
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0), 0.0)
    core.feed(packet(SensorType.IMU, 2, *IMU_LEVEL), 0.0)  # waits for 1
    outputs = core.feed(packet(SensorType.STOP, 1), 0.0)
    assert core.stopped
    assert outputs, "STOP flushes a last OUTPUT"
    core.feed(packet(SensorType.IMU, 3, *IMU_LEVEL), 0.0)
    assert core.counters.dropped["after_stop"] == 2
    assert core.counters.accounted(len(core.buffer)) == core.counters.received == 4


def test_imu_alone_is_degraded_and_a_silent_imu_and_odometer_is_lost(ring: TrackMap) -> None:
    """The first STROBE after GROUND_TRUTH sets the time base; silence is measured from it."""
    core = ListenerCore(ring, ListenerConfig(sensors=frozenset({"imu"})))
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0), 0.0)
    for seq in range(1, 80):
        core.feed(packet(SensorType.IMU, seq, *IMU_LEVEL), 0.0)
    assert core.status is not None
    assert core.status.health is Health.DEGRADED
    assert core.counters.processed["imu"] == 79
    everything = ListenerCore(ring)
    everything.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0), 0.0)
    everything.feed(packet(SensorType.STROBE, 1, 0.0), 0.0)
    everything.feed(packet(SensorType.IMU, 2, *IMU_LEVEL), 0.0)
    for second in range(1, 6):  # the IMU and the odometer silent: STROBEs alone, once a second
        everything.feed(packet(SensorType.STROBE, 2 + second, float(second)), 0.0)
    everything.feed(packet(SensorType.GPS, 8, 44.512, 11.318, 42.0), 0.0)
    assert everything.status is not None
    assert everything.status.health is Health.LOST


def test_fuzz_ten_thousand_datagrams_all_accounted() -> None:
    result = fuzz_listener(10_000, seed=11)
    assert result.fed == result.received == result.accounted == 10_000
    assert result.processed["imu"] > 100
    assert result.dropped["length_mismatch"] > 100


@pytest.mark.timeout(60)
def test_fuzz_over_udp_into_a_running_listener(ring: TrackMap) -> None:
    core = ListenerCore(ring)
    datagrams = [d for d in fuzz_datagrams(np.random.default_rng(5), 3000) if d[:1] != bytes([10])]
    stop = threading.Event()

    def received_more_than(count: int) -> Callable[[], bool]:
        return lambda: core.counters.received > count

    with ListenerRunner(
        core, input_address=("127.0.0.1", 0), obcu_address=("127.0.0.1", 9)
    ) as runner:
        thread = threading.Thread(target=runner.run, args=(stop,))
        thread.start()
        try:
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
                for index, datagram in enumerate(datagrams):
                    sender.sendto(datagram, runner.input_address)
                    if index % 100 == 99:
                        wait_for(received_more_than(index - 50), timeout_s=5.0)
            assert wait_for(lambda: core.counters.received == len(datagrams), timeout_s=20.0)
        finally:
            stop.set()
            thread.join(timeout=10.0)
    assert not thread.is_alive()
    counters = core.counters
    assert counters.accounted(len(core.buffer)) == counters.received == len(datagrams)


def test_a_restarted_sender_is_followed_to_its_new_time_base(ring: TrackMap) -> None:
    core = ListenerCore(ring)
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.0), 0.0)
    core.feed(packet(SensorType.STROBE, 1, 1000.0), 0.0)
    core.feed(packet(SensorType.IMU, 2, *IMU_LEVEL), 0.0)
    assert core.filter.epoch_s == pytest.approx(1000.0)
    # The sender restarts: SEQ_NO from 0 again, GROUND_TRUTH first, its clock from 0.
    for seq in range(3, 2000):
        core.feed(packet(SensorType.IMU, seq, *IMU_LEVEL), 0.0)
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 0.0, 0.0, 0.0, 0.2), 1.0)
    core.feed(packet(SensorType.STROBE, 1, 0.0), 1.0)
    core.feed(packet(SensorType.IMU, 2, *IMU_LEVEL), 1.0)
    assert core.counters.processed["ground_truth"] == 2
    assert core.filter.epoch_s == pytest.approx(0.0)
    assert core.status is not None
    assert core.status.chainage_m == pytest.approx(200.0, abs=0.1)
    assert core.status.health is Health.OK


def test_the_filters_gating_is_counted_for_the_listeners_user(ring: TrackMap) -> None:
    core = ListenerCore(ring)
    core.feed(packet(SensorType.GROUND_TRUTH, 0, 10.0, 0.0, 0.0, 0.5), 0.0)
    core.feed(packet(SensorType.STROBE, 1, 0.0), 0.0)
    core.feed(packet(SensorType.ODOMETER, 2, 10.0, 0.05), 0.0)
    core.feed(packet(SensorType.ODOMETER, 3, 40.0, 0.05), 0.05)  # no train jumps to 144 km/h
    latitude, longitude, _ = ring.geodetic_at(600.0)  # 100 m off the estimate: gated out
    core.feed(packet(SensorType.GPS, 4, latitude, longitude, 0.0), 0.1)
    core.poll(1.0)
    assert core.filter_counters() == {
        "imu_accepted": 0,
        "imu_rejected": 0,
        "odometer_accepted": 1,
        "odometer_rejected": 1,
        "gps_accepted": 0,
        "gps_rejected": 1,
        "fix_accepted": 0,
        "gps_reanchored": 0,
    }
