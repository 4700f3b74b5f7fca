"""The OBCU side: newest epoch wins, ACKs each second, unwrapping, staleness, fixes."""

from __future__ import annotations

import pytest

from onboard.sfa import Health, Localisation
from protocol.udp import OutputPacket, decode_ack, encode_output
from trackdb import TrackMap, load_seed_line


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line("bologna-ring"))


def output(seq: int, epoch_s: float, chainage_m: float) -> bytes:
    return encode_output(OutputPacket(seq, epoch_s, chainage_m / 1000.0))


def test_the_newest_epoch_wins_whatever_the_order(ring: TrackMap) -> None:
    localisation = Localisation(ring)
    localisation.receive(output(0, 1.0, 100.0), 1.0)
    localisation.receive(output(2, 1.2, 102.0), 1.2)
    localisation.receive(output(1, 1.1, 101.0), 1.2)
    localisation.step(1.2)
    estimate = localisation.estimate
    assert estimate is not None
    assert estimate.position_m == pytest.approx(102.0)
    assert estimate.speed_mps == pytest.approx(10.0)
    assert localisation.counters["older"] == 1
    assert estimate.imu_alive is None  # no listener attached


def test_acks_carry_the_last_seq_once_a_second(ring: TrackMap) -> None:
    localisation = Localisation(ring)
    acks: list[int] = []
    for tick in range(31):
        now_s = 10.0 + tick * 0.1
        localisation.receive(output(tick, now_s, 100.0 + tick), now_s)
        acks += [decode_ack(a).seq_no for a in localisation.step(now_s)]
    assert acks == [0, 10, 20, 30]


def test_position_is_unwrapped_across_the_ring_origin(ring: TrackMap) -> None:
    localisation = Localisation(ring)
    lap = ring.length_m
    localisation.receive(output(0, 1.0, lap - 5.0), 1.0)
    localisation.receive(output(1, 2.0, 5.0), 2.0)
    localisation.step(2.0)
    estimate = localisation.estimate
    assert estimate is not None
    assert estimate.position_m == pytest.approx(lap + 5.0)
    assert estimate.chainage_m == pytest.approx(5.0)


def test_no_output_for_a_second_means_lost_and_garbage_is_counted(ring: TrackMap) -> None:
    localisation = Localisation(ring)
    localisation.receive(b"\x00" * 5, 0.0)
    assert localisation.counters["malformed"] == 1
    assert localisation.step(0.0) == []
    assert localisation.estimate is None
    localisation.receive(output(0, 1.0, 100.0), 1.0)
    localisation.step(1.5)
    assert localisation.estimate is not None
    assert localisation.estimate.health is Health.OK
    localisation.step(2.1)
    assert localisation.estimate.health is Health.LOST


def test_a_fix_without_listener_shifts_the_position(ring: TrackMap) -> None:
    localisation = Localisation(ring)
    localisation.receive(output(0, 1.0, 100.0), 1.0)
    localisation.fix(103.0, 0.5, 1.0)
    localisation.step(1.0)
    assert localisation.estimate is not None
    assert localisation.estimate.position_m == pytest.approx(103.0)
    with pytest.raises(ValueError, match="not valid"):
        localisation.fix(float("nan"), 0.5, 1.0)


def test_after_a_silence_a_restarted_listener_is_followed(ring: TrackMap) -> None:
    localisation = Localisation(ring)
    localisation.receive(output(0, 500.0, 100.0), 500.0)
    localisation.receive(output(0, 0.0, 50.0), 500.5)
    assert localisation.counters["older"] == 1
    localisation.receive(output(1, 0.05, 50.5), 502.0)
    localisation.step(502.0)
    assert localisation.counters["resynchronised"] == 1
    assert localisation.estimate is not None
    assert localisation.estimate.epoch_s == 0.05
