"""The interface-modules emulator and the offline configuration (record, replay)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from deploy.bench.sfa_drive import DriveSettings
from deploy.bench.sfa_lockstep import run_lockstep
from deploy.bench.sfa_recording import Recording, RecordingError, replay
from onboard.plant.sensors import (
    InterfaceModules,
    SensorFaults,
    TimeWindow,
    TruthSample,
)
from onboard.sfa import FilterConfig, ListenerConfig
from protocol.udp import SensorType, decode_input
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.scenario


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line("bologna-ring"))


def test_imu_at_rest_on_a_gradient_and_the_sequence_counter(ring: TrackMap) -> None:
    modules = InterfaceModules(ring, rng=np.random.default_rng(0))
    standing = TruthSample(time_s=0.0, position_m=100.0, speed_mps=0.0, acceleration_mps2=0.0)
    packets = [decode_input(d) for d in modules.start(standing) + modules.step(standing)]
    assert [p.sensor_type for p in packets] == [
        SensorType.GROUND_TRUTH,
        SensorType.STROBE,
        SensorType.IMU,
        SensorType.ODOMETER,
        SensorType.GPS,
    ]
    assert [p.seq_no for p in packets] == [0, 1, 2, 3, 4]
    acc_x, acc_y, acc_z = packets[2].doubles[:3]
    uphill = 9.81 * np.sin(np.arctan(2.0 / 1000.0))
    assert acc_x == pytest.approx(uphill, abs=0.25)  # within the bias and noise
    assert acc_z == pytest.approx(-9.81, abs=0.25)
    assert abs(acc_y) < 0.25


def test_in_a_left_curve_the_lateral_force_points_left_and_the_yaw_rate_is_negative(
    ring: TrackMap,
) -> None:
    modules = InterfaceModules(ring, rng=np.random.default_rng(0))
    in_curve = TruthSample(time_s=0.0, position_m=1300.0, speed_mps=16.0, acceleration_mps2=0.0)
    modules.start(in_curve)
    imu = next(p for p in map(decode_input, modules.step(in_curve)) if p.sensor_type == 1)
    assert imu.doubles[1] == pytest.approx(-(16.0**2) / 400.0, abs=0.25)
    assert imu.doubles[5] == pytest.approx(-16.0 / 400.0, abs=0.01)


def test_gps_outage_and_odometer_outage_send_nothing(ring: TrackMap) -> None:
    faults = SensorFaults(
        gps_outages=(TimeWindow(0.0, 10.0),), odometer_outages=(TimeWindow(0.0, 10.0),)
    )
    modules = InterfaceModules(ring, rng=np.random.default_rng(0), faults=faults)
    standing = TruthSample(time_s=0.0, position_m=0.0, speed_mps=0.0, acceleration_mps2=0.0)
    modules.start(standing)
    types = {decode_input(d).sensor_type for _ in range(200) for d in modules.step(standing)}
    assert types == {SensorType.STROBE, SensorType.IMU}


def test_record_save_load_replay_matches_the_online_run(ring: TrackMap, tmp_path: Path) -> None:
    result = run_lockstep(DriveSettings(duration_s=60.0, seed=9, record=True), ring)
    assert result.recording is not None
    path = tmp_path / "drive.npz"
    result.recording.save(path)
    loaded = Recording.load(path)
    assert loaded.datagrams == result.recording.datagrams
    everything = replay(loaded, track_map=ring)
    assert everything.position_rms_m <= 1.0
    assert everything.speed_rms_kmh <= 0.2
    assert everything.epochs_s.size == result.listener.counters.outputs_sent
    # The offline switches: the IMU alone is much worse, a looser GPS σ changes the numbers.
    imu_only = replay(loaded, ListenerConfig(sensors=frozenset({"imu"})), ring)
    assert imu_only.position_rms_m > 5 * everything.position_rms_m
    loose_gps = replay(loaded, ListenerConfig(filter=FilterConfig(gps_sigma_m=30.0)), ring)
    assert loose_gps.position_rms_m != everything.position_rms_m


def test_unreadable_recording_raises_a_typed_error(tmp_path: Path) -> None:
    path = tmp_path / "bad.npz"
    path.write_bytes(b"not a zip")
    with pytest.raises(RecordingError):
        Recording.load(path)
    with pytest.raises(RecordingError):
        Recording.load(tmp_path / "missing.npz")


def test_with_the_bogie_model_the_odometer_reads_the_wheel_so_slip_shows(ring: TrackMap) -> None:
    from onboard.plant.interfaces import BogieTruth
    from onboard.plant.sensors import SensorNoise, truth_from_bogie

    slipping = BogieTruth(
        time_s=0.0,
        position_m=10.0,
        speed_mps=10.0,
        acceleration_mps2=0.5,
        wheel_speed_front_radps=25.0,
        wheel_speed_rear_radps=24.0,
        wheel_radius_m=0.46,
        motor_torque_front_nm=0.0,
        motor_torque_rear_nm=0.0,
        brake_torque_front_nm=0.0,
        brake_torque_rear_nm=0.0,
        normal_force_front_n=0.0,
        normal_force_rear_n=0.0,
        creepage_front=0.15,
        creepage_rear=0.1,
        traction_energy_j=0.0,
        regen_energy_j=0.0,
    )
    modules = InterfaceModules(ring, rng=np.random.default_rng(0), noise=SensorNoise.noiseless())
    truth = truth_from_bogie(slipping)
    modules.start(truth)
    odometer = next(p for p in map(decode_input, modules.step(truth)) if p.sensor_type == 2)
    speed_mps, sigma_mps = odometer.doubles
    assert speed_mps == pytest.approx(25.0 * 0.46)
    assert sigma_mps == 0.0
