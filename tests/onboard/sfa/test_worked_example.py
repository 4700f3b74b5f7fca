"""Seed 002 §3.3, the worked example, over real UDP sockets on 127.0.0.1.

GROUND_TRUTH with zero velocity at 0 km (SEQ_NO 0), then IMU packets at 100 Hz with the
example's values (the first with SEQ_NO 1), the odometer's 1.0010 m/s at 20 Hz from t0 + 1/20,
and a STROBE every second: the listener initialises, sends OUTPUT datagrams numbered from 0 to
the OBCU, and the OBCU's ACKs reach it.
"""

from __future__ import annotations

import socket
import threading

import pytest

from onboard.sfa import Health, ListenerCore, Localisation
from onboard.sfa.sockets import ListenerRunner, ObcuEndpoint
from protocol.udp import InputPacket, SensorType, decode_output, encode_input
from tests.conftest import wait_for
from trackdb import TrackMap, load_seed_line

EXAMPLE_IMU = (0.0001, -0.0001, -9.8100, 0.0003, -0.0001, 0.0002)
EXAMPLE_ODOMETER_MPS = 1.0010
SIGMA_RADAR_MPS = 0.05


def example_stream(seconds: int) -> list[bytes]:
    packets = [InputPacket(SensorType.GROUND_TRUTH, 0, (0.0, 0.0, 0.0, 0.0))]
    for tick in range(100 * seconds):
        if tick and tick % 100 == 0:
            packets.append(InputPacket(SensorType.STROBE, len(packets), (tick / 100.0,)))
        packets.append(InputPacket(SensorType.IMU, len(packets), EXAMPLE_IMU))
        if tick % 5 == 4:
            packets.append(
                InputPacket(
                    SensorType.ODOMETER, len(packets), (EXAMPLE_ODOMETER_MPS, SIGMA_RADAR_MPS)
                )
            )
    return [encode_input(packet) for packet in packets]


def test_example_stream_has_the_seeds_header_bytes() -> None:
    stream = example_stream(1)
    assert stream[0][:5] == bytes([0x08, 0x00, 0x00, 0x00, 0x04])
    assert stream[1][:5] == bytes([0x01, 0x01, 0x00, 0x00, 0x06])
    assert stream[6][:5] == bytes([0x02, 0x06, 0x00, 0x00, 0x02])


@pytest.mark.timeout(60)
def test_worked_example_over_udp_initialises_outputs_from_zero_and_is_acknowledged() -> None:
    track_map = TrackMap(load_seed_line("bologna-ring"))
    core = ListenerCore(track_map)
    localisation = Localisation(track_map)
    obcu = ObcuEndpoint(localisation, ("127.0.0.1", 0))
    outputs: list[bytes] = []
    original_receive = localisation.receive

    def keep(datagram: bytes, arrival_s: float) -> None:
        outputs.append(datagram)
        original_receive(datagram, arrival_s)

    localisation.receive = keep  # type: ignore[method-assign]
    stop = threading.Event()
    exit_status: list[int] = []
    with ListenerRunner(core, input_address=("127.0.0.1", 0), obcu_address=obcu.address) as runner:
        thread = threading.Thread(target=lambda: exit_status.append(runner.run(stop)))
        thread.start()
        try:
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
                for datagram in example_stream(3):
                    sender.sendto(datagram, runner.input_address)

                def acknowledged() -> bool:
                    obcu.poll()
                    return core.counters.acks_received >= 1

                assert wait_for(acknowledged, timeout_s=20.0)
                sender.sendto(
                    encode_input(InputPacket(SensorType.STOP, 1000, ())), runner.input_address
                )
                thread.join(timeout=20.0)
                # What the listener sent after the first ACK (on a loaded machine it may still
                # have been working through the burst then) waits in the OBCU's socket.
                obcu.poll()
        finally:
            stop.set()
            thread.join(timeout=5.0)
            obcu.close()
    assert exit_status == [0]
    assert core.counters.processed["ground_truth"] == 1
    assert core.counters.processed["imu"] == 300
    assert core.counters.processed["stop"] == 1
    decoded = [decode_output(datagram) for datagram in outputs]
    assert decoded, "no OUTPUT datagram reached the OBCU"
    assert [packet.seq_no for packet in decoded] == list(range(len(decoded)))
    assert decoded[0].epoch_s == 0.0
    # At least 10 outputs per second of sensor time, and the train has hardly moved from 0 km
    # (on the ring, a hair behind the origin reads as the ring's length).
    assert len(decoded) >= 30
    ring_km = track_map.length_m / 1000.0
    for packet in decoded:
        assert 0.0 <= packet.arc_length_km < ring_km
        assert min(packet.arc_length_km, ring_km - packet.arc_length_km) < 0.01
    assert core.last_ack_seq is not None
    assert core.last_ack_seq <= decoded[-1].seq_no
    assert localisation.estimate is not None
    assert localisation.estimate.health is not Health.LOST
