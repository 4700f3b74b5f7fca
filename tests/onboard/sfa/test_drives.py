"""The whole chain in lockstep on shortened drives: the issue's accuracy targets, failure
detection and determinism. ``ato bench sfa`` runs the full-length drives."""

from __future__ import annotations

import numpy as np
import pytest

from deploy.bench.sfa_drive import DriveSettings
from deploy.bench.sfa_lockstep import run_lockstep
from onboard.plant.sensors import SensorFaults, TimeWindow
from onboard.sfa import Health, LinkFaults, ListenerConfig
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.scenario

RING_S = 200.0


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line("bologna-ring"))


@pytest.fixture(scope="module")
def milano() -> TrackMap:
    return TrackMap(load_seed_line("milano-bologna"))


def test_ring_all_sensors_within_a_metre_and_speed_within_0_2_kmh(ring: TrackMap) -> None:
    result = run_lockstep(DriveSettings(duration_s=RING_S, seed=1), ring)
    stats = result.stats()
    assert stats.samples == 20001
    assert stats.position_rms_m <= 1.0
    assert stats.speed_rms_kmh <= 0.2
    assert result.listener.counters.processed["imu"] == 20001
    assert result.localisation.counters["acks_sent"] >= RING_S - 1
    assert not result.listener.link_lost(RING_S)


def test_milano_at_300_kmh_within_a_metre(milano: TrackMap) -> None:
    result = run_lockstep(
        DriveSettings(line_id="milano-bologna", duration_s=150.0, cruise_kmh=300.0, seed=2),
        milano,
    )
    assert result.localisation.estimate is not None
    assert result.localisation.estimate.speed_mps > 40.0
    stats = result.stats()
    assert stats.position_rms_m <= 1.0
    assert stats.speed_rms_kmh <= 0.2


def test_sixty_second_gps_outage_stays_within_ten_metres(ring: TrackMap) -> None:
    outage = TimeWindow(60.0, 120.0)
    result = run_lockstep(
        DriveSettings(duration_s=130.0, seed=3, sensor_faults=SensorFaults(gps_outages=(outage,))),
        ring,
    )
    assert result.stats(outage).position_max_m <= 10.0
    assert result.listener.status is not None
    assert result.listener.status.gps_alive


def test_twenty_percent_loss_with_reordering_within_two_metres(milano: TrackMap) -> None:
    result = run_lockstep(
        DriveSettings(
            line_id="milano-bologna",
            duration_s=150.0,
            cruise_kmh=300.0,
            seed=4,
            link_faults=LinkFaults(loss_rate=0.2, reorder_rate=0.2),
        ),
        milano,
    )
    assert result.stats().position_rms_m <= 2.0
    assert result.link.counters["lost"] > 0.15 * result.link.counters["sent"]
    assert result.listener.buffer.lost > 0


@pytest.mark.parametrize(
    "faults",
    [
        SensorFaults(odometer_outages=(TimeWindow(60.0, 1e9),)),
        SensorFaults(odometer_stuck_at_zero=(TimeWindow(60.0, 1e9),)),
    ],
    ids=["silent", "stuck-at-zero"],
)
def test_odometer_failure_is_detected_within_a_second(ring: TrackMap, faults: SensorFaults) -> None:
    result = run_lockstep(DriveSettings(duration_s=70.0, seed=5, sensor_faults=faults), ring)
    assert bool(result.odometer_alive[result.times_s < 60.0].all())
    delay = result.detection_delay_s(60.0)
    assert delay is not None
    assert delay <= 1.0
    estimate = result.localisation.estimate
    assert estimate is not None
    assert estimate.health is Health.DEGRADED
    assert estimate.odometer_alive is False
    assert result.stats(TimeWindow(60.0, 70.0)).position_max_m <= 5.0


def test_imu_alone_runs_degraded(ring: TrackMap) -> None:
    result = run_lockstep(
        DriveSettings(duration_s=30.0, seed=6, listener=ListenerConfig(sensors=frozenset({"imu"}))),
        ring,
    )
    estimate = result.localisation.estimate
    assert estimate is not None
    assert estimate.health is Health.DEGRADED
    assert result.listener.counters.disabled > 0
    assert result.stats().position_max_m < 100.0


def test_same_seed_same_numbers_bit_for_bit(ring: TrackMap) -> None:
    settings = DriveSettings(
        duration_s=20.0,
        seed=7,
        link_faults=LinkFaults(
            loss_rate=0.1, reorder_rate=0.1, duplicate_rate=0.05, corrupt_rate=0.05
        ),
    )
    first, second = run_lockstep(settings, ring), run_lockstep(settings, ring)
    assert np.array_equal(first.position_errors_m, second.position_errors_m)
    assert first.listener.counters == second.listener.counters
    assert first.listener.counters.dropped["duplicate"] > 0


def test_a_ring_lap_is_unwrapped_in_the_position(ring: TrackMap) -> None:
    result = run_lockstep(DriveSettings(duration_s=20.0, seed=8, start_m=ring.length_m - 100.0))
    estimate = result.localisation.estimate
    assert estimate is not None
    assert estimate.position_m > ring.length_m
    assert estimate.chainage_m == pytest.approx(estimate.position_m - ring.length_m)
    assert result.stats().position_max_m < 1.5


def test_a_dead_bus_makes_the_estimate_lost_and_it_recovers(ring: TrackMap) -> None:
    dead = TimeWindow(20.0, 23.0)
    result = run_lockstep(
        DriveSettings(duration_s=30.0, seed=10, link_faults=LinkFaults(dead_windows=(dead,))),
        ring,
    )
    assert result.link.counters["dead_bus"] > 300
    times = result.times_s
    assert not result.lost[times < 20.0].any()
    assert result.lost[(times > 21.1) & (times < 23.0)].all()
    assert not result.lost[times > 23.1].any()
    # The Localisation extrapolated through the silence and resynchronised after it.
    assert result.stats(TimeWindow(24.0, 30.0)).position_max_m < 2.0
    assert result.localisation.estimate is not None
    assert result.localisation.estimate.health is Health.OK
