"""The along-track Kalman filter: prediction equal to filterpy's, gating, IMU-only growth,
balise fixes, ring unwrapping."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from numpy.testing import assert_allclose

from onboard.sfa import FilterConfig, NotInitialisedError, TrackKalmanFilter
from onboard.sfa.filter import transition_matrices
from trackdb import TrackMap, load_seed_line


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line("bologna-ring"))


def test_fast_prediction_equals_filterpys(ring: TrackMap) -> None:
    fast = TrackKalmanFilter(ring)
    fast.initialise(100.0, 12.0, 0.0)
    fast.kf.x[2, 0] = 0.03
    reference = KalmanFilter(dim_x=3, dim_z=1)
    reference.x = fast.kf.x.copy()
    reference.P = fast.kf.P.copy()
    rng = np.random.default_rng(4)
    for dt_s in rng.uniform(0.005, 0.05, size=200):
        u = float(rng.normal(0.0, 0.5))
        transition, control, process = transition_matrices(float(dt_s), fast.config)
        reference.predict(u=np.array([[u]]), B=control, F=transition, Q=process)
        fast.predict(float(dt_s), u)
    assert_allclose(fast.kf.x, reference.x, rtol=1e-12, atol=1e-9)
    assert_allclose(fast.kf.P, reference.P, rtol=1e-10, atol=1e-12)


def test_scalar_update_equals_filterpys_bit_for_bit(ring: TrackMap) -> None:
    fast = TrackKalmanFilter(ring)
    fast.initialise(100.0, 12.0, 0.0)
    reference = KalmanFilter(dim_x=5, dim_z=1)
    reference.inv = lambda matrix: np.array([[1.0 / float(matrix[0, 0])]])
    reference.x = fast.kf.x.copy()
    reference.P = fast.kf.P.copy()
    rng = np.random.default_rng(24)
    for step in range(300):
        dt_s, u = float(rng.uniform(0.005, 0.05)), float(rng.normal(0.0, 0.5))
        fast.predict(dt_s, u)
        reference.x, reference.P = fast.kf.x.copy(), fast.kf.P.copy()
        if step % 3 == 0:
            h = np.array([[1.0, -0.1, 0.0, 0.0, 1.0]])
        else:
            h = np.array([[0.0, 1.0 + rng.normal(0, 0.01), rng.uniform(0, 0.03), 12.0, 0.0]])
        z, variance = float(rng.normal(fast.kf.x[1, 0], 0.2)), float(rng.uniform(1e-4, 0.1))
        fast._update(z, h, variance)
        reference.update(np.array([[z]]), R=np.array([[variance]]), H=h)
        np.testing.assert_array_equal(fast.kf.x, reference.x)
        np.testing.assert_array_equal(fast.kf.P, reference.P)


def test_estimate_before_ground_truth_raises(ring: TrackMap) -> None:
    with pytest.raises(NotInitialisedError):
        _ = TrackKalmanFilter(ring).chainage_m


def test_odometer_outlier_is_gated_and_a_consistent_one_accepted(ring: TrackMap) -> None:
    flt = TrackKalmanFilter(ring)
    flt.initialise(0.0, 10.0, 0.0)
    assert flt.odometer(0.05, 10.02, 0.05)
    assert not flt.odometer(0.10, 30.0, 0.05)
    assert flt.rejected["odometer"] == 1
    assert flt.accepted["odometer"] == 1
    assert flt.speed_mps == pytest.approx(10.0, abs=0.05)


def test_imu_alone_lets_sigma_grow_and_a_balise_fix_shrinks_it(ring: TrackMap) -> None:
    flt = TrackKalmanFilter(ring)
    flt.initialise(0.0, 10.0, 0.0)
    level_at_rest = 9.81 * float(np.sin(np.arctan(2.0 / 1000.0)))  # the first straight: 2 ‰
    for tick in range(1, 1001):
        flt.imu(tick * 0.01, level_at_rest)
    assert flt.chainage_m == pytest.approx(100.0, abs=1e-6)
    grown = flt.position_sigma_m
    assert grown > 5.0
    flt.fix(100.5, 0.5, 10.0)
    assert flt.position_sigma_m < 0.5
    assert flt.chainage_m == pytest.approx(100.5, abs=0.1)


def test_gravity_of_the_gradient_is_taken_out_of_the_forward_specific_force(
    ring: TrackMap,
) -> None:
    flt = TrackKalmanFilter(ring)
    flt.initialise(100.0, 0.0, 0.0)  # on the first straight, 2 ‰ uphill
    at_rest_uphill = 9.81 * np.sin(np.arctan(2.0 / 1000.0))
    assert flt.forward_specific_force_to_input(float(at_rest_uphill)) == pytest.approx(
        0.0, abs=1e-12
    )


def test_gps_and_fixes_unwrap_to_the_lap_of_the_estimate(ring: TrackMap) -> None:
    config = FilterConfig(gps_sigma_m=2.0, gps_latency_s=0.0, gps_correlated_sigma_m=0.0)
    flt = TrackKalmanFilter(ring, config)
    lap = ring.length_m
    flt.initialise(lap + 5.0, 10.0, 0.0)  # second lap, 5 m past the origin
    assert flt.unwrap_near_estimate(lap - 3.0) == pytest.approx(lap - 3.0)
    latitude, longitude, _ = ring.geodetic_at(6.0)
    assert flt.gps(0.0, latitude, longitude)
    # σ 1 m against the fix's 2 m: a fifth of the way to it, on the second lap.
    assert flt.chainage_m == pytest.approx(lap + 5.2, abs=0.05)


def test_gps_fix_far_off_the_track_is_rejected(ring: TrackMap) -> None:
    flt = TrackKalmanFilter(ring)
    flt.initialise(0.0, 10.0, 0.0)
    latitude, longitude, _ = ring.geodetic_at(0.0)
    assert not flt.gps(0.0, latitude + 0.01, longitude)
    assert flt.rejected["gps"] == 1


def test_a_gps_fix_is_taken_as_the_position_latency_ago(ring: TrackMap) -> None:
    flt = TrackKalmanFilter(ring, FilterConfig(gps_latency_s=0.2))
    flt.initialise(100.0, 20.0, 0.0)
    latitude, longitude, _ = ring.geodetic_at(100.0 - 20.0 * 0.2)
    assert flt.gps(0.0, latitude, longitude)
    assert flt.chainage_m == pytest.approx(100.0, abs=0.01)


def test_the_odometer_scale_error_is_learnt_against_the_gps(ring: TrackMap) -> None:
    """A wheel 2 % worn: the odometer reads 2 % fast; the GPS and the IMU teach the filter."""
    flt = TrackKalmanFilter(ring, FilterConfig(gps_latency_s=0.0))
    speed_mps, start_m = 15.0, 100.0
    flt.initialise(start_m, speed_mps, 0.0)
    for tick in range(1, 120 * 20 + 1):
        time_s = tick * 0.05
        flt.predict_to(time_s)
        flt.odometer(time_s, 1.02 * speed_mps, 0.05)
        if tick % 20 == 0:
            latitude, longitude, _ = ring.geodetic_at(start_m + speed_mps * time_s)
            flt.gps(time_s, latitude, longitude)
    assert flt.odometer_scale_error == pytest.approx(0.02, abs=0.001)
    assert flt.speed_mps == pytest.approx(speed_mps, abs=0.02)
    assert flt.chainage_m == pytest.approx(start_m + speed_mps * 120.0, abs=0.5)
    assert flt.rejected == {"imu": 0, "odometer": 0, "gps": 0}


def test_a_multipath_jump_is_gated_and_a_lasting_shift_reanchors(ring: TrackMap) -> None:
    config = FilterConfig(gps_latency_s=0.0)
    flt = TrackKalmanFilter(ring, config)
    flt.initialise(500.0, 0.0, 0.0)
    latitude, longitude, _ = ring.geodetic_at(508.0)  # 8 m ahead of a train at a standstill

    def standstill_until(time_s: float) -> None:
        while flt.epoch_s < time_s - 1e-9:
            flt.odometer(flt.epoch_s + 0.05, 0.0, 0.05)

    for second in range(config.gps_reanchor_after):
        standstill_until(float(second))
        assert not flt.gps(float(second), latitude, longitude)
    assert flt.rejected["gps"] == config.gps_reanchor_after
    assert flt.reanchored == 0
    assert flt.chainage_m == pytest.approx(500.0, abs=1e-6)
    standstill_until(float(config.gps_reanchor_after))
    assert flt.gps(float(config.gps_reanchor_after), latitude, longitude)
    assert flt.reanchored == 1
    assert flt.chainage_m > 505.0


def test_a_balise_fix_calibrates_the_gps_correlated_error(ring: TrackMap) -> None:
    flt = TrackKalmanFilter(ring, FilterConfig(gps_latency_s=0.0))
    flt.initialise(500.0, 0.0, 0.0)
    latitude, longitude, _ = ring.geodetic_at(500.4)  # the GPS reads 0.4 m ahead, for minutes

    def standstill(seconds: range) -> None:
        for second in seconds:
            while flt.epoch_s < second - 1e-9:
                flt.odometer(flt.epoch_s + 0.05, 0.0, 0.05)
            flt.gps(float(second), latitude, longitude)

    standstill(range(1, 31))
    assert flt.chainage_m > 500.15  # pulled towards the GPS
    flt.fix(500.0, 0.05, 30.0)
    assert flt.gps_error_m == pytest.approx(0.4, abs=0.1)
    standstill(range(31, 41))
    # The GPS's error is known now: its fixes no longer pull the estimate away.
    assert flt.chainage_m == pytest.approx(500.0, abs=0.06)


@pytest.mark.parametrize(("window_s", "bias_limit_mps"), [(0.05, 0.002), (0.0, 0.02)])
def test_the_odometers_counting_window_is_modelled(
    ring: TrackMap, window_s: float, bias_limit_mps: float
) -> None:
    """Braking at 0.5 m/s²: the odometer's count over 50 ms gives the speed 25 ms ago."""
    config = FilterConfig(odometer_window_s=window_s, gps_latency_s=0.0)
    flt = TrackKalmanFilter(ring, config)
    flt.initialise(100.0, 20.0, 0.0)
    deceleration, errors = 0.5, []
    for tick in range(1, 3001):  # 30 s at 100 Hz
        time_s = tick * 0.01
        flt.last_input_mps2 = -deceleration
        flt.predict_to(time_s)
        if tick % 5 == 0:
            flt.odometer(time_s, 20.0 - deceleration * (time_s - 0.025), 0.05)
            errors.append(flt.speed_mps - (20.0 - deceleration * time_s))
    late = float(np.mean(errors[-200:]))
    if window_s:
        assert abs(late) < bias_limit_mps
    else:  # unmodelled, the lag shows as a speed read high (by up to 12.5 mm/s)
        assert 0.005 < late < bias_limit_mps


def test_with_a_dead_imu_the_odometer_follows_the_traction(ring: TrackMap) -> None:
    """A dead IMU: the prediction runs at constant speed and the unknown input must admit the
    URV's traction (1.8 m/s² held for seconds), else the odometer's speeds are gated out and the
    position runs on at the speed the train had (gen-1-52: 7.6 m behind)."""
    flt = TrackKalmanFilter(ring)
    flt.initialise(0.0, 10.0, 0.0)
    flt.unknown_input_sigma_mps2 = 0.5  # what the listener sets while the IMU is dead
    rng = np.random.default_rng(7)
    window_s, sigma_mps = flt.config.odometer_window_s, 0.06
    position, speed = 0.0, 10.0
    for tick in range(1, 201):  # 10 s at 20 Hz: 4 s of traction, then coasting
        acceleration = 1.8 if tick <= 80 else 0.0
        position += speed * 0.05 + 0.5 * acceleration * 0.05**2
        speed += acceleration * 0.05
        mean_speed = speed - 0.5 * acceleration * window_s
        flt.odometer(tick * 0.05, mean_speed + float(rng.normal(0.0, sigma_mps)), sigma_mps)
        # No GPS here: the speed's lag behind the traction runs into the position (< 1 m).
        assert flt.chainage_m == pytest.approx(position, abs=1.5)
    assert flt.rejected["odometer"] <= 2
    assert flt.speed_mps == pytest.approx(speed, abs=0.3)


def test_an_imu_sample_outside_the_vehicles_envelope_is_gated_out(ring: TrackMap) -> None:
    """One corrupted byte (an exponent bit) turns 2.2 m/s² into 35.5 m/s², within the
    listener's 100 m/s² range check: taken as the input for 10 ms it would add 0.33 m/s."""
    flt = TrackKalmanFilter(ring)
    flt.initialise(0.0, 10.0, 0.0)
    gravity = 9.81 * float(np.sin(np.arctan(2.0 / 1000.0)))  # the first straight: 2 ‰
    corrupted = bytearray(struct.pack("<d", 2.2 + gravity))
    corrupted[6] ^= 0x40
    spike = struct.unpack("<d", corrupted)[0]
    assert spike == pytest.approx(35.5, abs=0.1)
    for tick in range(1, 101):
        accepted = flt.imu(tick * 0.01, spike if tick == 50 else 2.2 + gravity)
        assert accepted is (tick != 50)
    assert flt.rejected["imu"] == 1
    assert flt.accepted["imu"] == 99
    assert flt.speed_mps == pytest.approx(12.2, abs=1e-6)
    for braking, accepted in ((-1.5, True), (-3.0, False), (2.5, True), (3.5, False)):
        assert flt.imu(flt.epoch_s + 0.01, braking + gravity) is accepted
