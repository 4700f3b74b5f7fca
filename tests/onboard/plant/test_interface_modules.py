"""The interface-modules' sensor errors: IMU scale factors and bias random walk, the odometer's
wheel scale and pulse quantisation, the GPS's latency, Gauss–Markov error and multipath, and
determinism per seed. Statistics over seeds or long series, each with an explicit tolerance."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from onboard.plant.sensors import InterfaceModules, SensorNoise, TruthSample
from protocol.udp import InputPacket, SensorType, decode_input
from protocol.units import GRAVITY_MPS2
from trackdb import TrackMap, load_seed_line

RING = TrackMap(load_seed_line("bologna-ring"))
NOISELESS = SensorNoise.noiseless()


def _modules(seed: int = 0, **errors: object) -> InterfaceModules:
    noise = dataclasses.replace(NOISELESS, **errors)  # type: ignore[arg-type]
    return InterfaceModules(RING, rng=np.random.default_rng(seed), noise=noise)


def _cruise(time_s: float, speed_mps: float = 20.0, start_m: float = 200.0) -> TruthSample:
    return TruthSample(
        time_s=time_s,
        position_m=start_m + speed_mps * time_s,
        speed_mps=speed_mps,
        acceleration_mps2=0.0,
    )


def _run(modules: InterfaceModules, seconds: float, speed_mps: float = 20.0) -> list[InputPacket]:
    """Start and step the modules at a steady speed; the decoded packets."""
    packets = [decode_input(d) for d in modules.start(_cruise(0.0, speed_mps))]
    for tick in range(round(seconds * modules.imu_rate_hz)):
        truth = _cruise(tick / modules.imu_rate_hz, speed_mps)
        packets += [decode_input(d) for d in modules.step(truth)]
    return packets


def test_noiseless_imu_is_the_truth_and_scale_factors_multiply_it() -> None:
    standing = TruthSample(time_s=0.0, position_m=100.0, speed_mps=0.0, acceleration_mps2=0.5)
    pitch = math.atan(2.0 / 1000.0)  # the first straight climbs 2 ‰
    exact = _modules().imu_sample(standing)
    assert_allclose(exact[0], 0.5 + GRAVITY_MPS2 * math.sin(pitch), atol=1e-12)
    assert_allclose(exact[2], -GRAVITY_MPS2 * math.cos(pitch), atol=1e-12)
    scaled = _modules(accelerometer_scale_sigma=0.01)
    sample = scaled.imu_sample(standing)
    assert_allclose(sample[0], scaled.accelerometer_scale[0] * exact[0], atol=1e-12)
    assert_allclose(sample[2], scaled.accelerometer_scale[2] * exact[2], atol=1e-12)
    factors = (
        np.array(
            [
                _modules(seed, accelerometer_scale_sigma=0.001).accelerometer_scale
                for seed in range(400)
            ]
        )
        - 1.0
    )
    # 1200 draws: the σ estimate's own σ is about 2 %.
    assert factors.std() == pytest.approx(0.001, rel=0.08)


def test_the_imu_bias_walks_as_a_random_walk_of_the_set_intensity() -> None:
    intensity, seconds = 1e-3, 9
    changes = []
    for seed in range(40):
        modules = _modules(
            seed,
            accelerometer_bias_walk_mps2_per_sqrt_s=intensity,
            gyro_bias_walk_radps_per_sqrt_s=intensity,
        )
        before = modules.accelerometer_bias_mps2 + modules.gyro_bias_radps
        _run(modules, seconds + 0.005)
        after = modules.accelerometer_bias_mps2 + modules.gyro_bias_radps
        changes += [b - a for a, b in zip(before, after, strict=True)]
    # 240 walks of 9 one-second steps: σ = intensity √9; the estimate's σ is about 5 %.
    assert np.std(changes) == pytest.approx(intensity * math.sqrt(seconds), rel=0.15)


def test_the_odometer_reads_the_worn_wheel_in_whole_counts() -> None:
    count_m = 0.0036
    modules = InterfaceModules(
        RING,
        rng=np.random.default_rng(0),
        noise=dataclasses.replace(NOISELESS, odometer_count_m=count_m),
        diameter_error=0.02,
    )
    packets = _run(modules, 30.0, speed_mps=13.7)
    odometer = [p.doubles for p in packets if p.sensor_type is SensorType.ODOMETER]
    speeds = np.array([speed for speed, _ in odometer])
    resolution = count_m / modules.odometer_period_s
    assert_allclose(speeds / resolution, np.round(speeds / resolution), atol=1e-6)
    assert np.abs(speeds - 1.02 * 13.7).max() <= resolution + 1e-9
    # Quantisation does not drift: over 30 s the mean is the scaled speed to within a count.
    assert speeds[1:].mean() == pytest.approx(1.02 * 13.7, abs=2 * count_m / 30.0)
    # σ sent: the quantisation's, LSB / √6 (the white noise is off).
    assert odometer[0][1] == pytest.approx(resolution / math.sqrt(6.0))


def test_a_gps_fix_is_of_the_position_latency_ago() -> None:
    modules = _modules(gps_latency_s=0.2)
    fixes = [p.doubles for p in _run(modules, 5.0) if p.sensor_type is SensorType.GPS]
    for second, (latitude, longitude, _) in enumerate(fixes):
        projection = RING.project(latitude, longitude, near_m=200.0 + 20.0 * second)
        assert projection.chainage_m == pytest.approx(200.0 + 20.0 * (second - 0.2), abs=0.01)


def test_the_gps_error_is_gauss_markov_with_its_sigma_and_correlation_time() -> None:
    sigma_m, tau_s = 1.0, 20.0
    modules = _modules(3, gps_correlated_horizontal_sigma_m=sigma_m, gps_correlation_time_s=tau_s)
    errors = []
    for second in range(20_000):
        modules.gps_sample(_cruise(float(second), speed_mps=0.0))
        errors.append(modules.gps_error_m[:2])
    north, east = np.array(errors).T
    for series in (north, east):
        # About 500 correlation times: the variance is known to about 10 %.
        assert series.var() == pytest.approx(sigma_m**2, rel=0.25)
        lag_one = np.corrcoef(series[:-1], series[1:])[0, 1]
        assert lag_one == pytest.approx(math.exp(-1.0 / tau_s), abs=0.02)
    assert abs(np.corrcoef(north, east)[0, 1]) < 0.15


def test_multipath_jumps_are_rare_offsets_of_set_size_and_duration() -> None:
    modules = _modules(
        4,
        gps_multipath_rate_per_s=0.02,
        gps_multipath_offset_m=(5.0, 5.0),
        gps_multipath_duration_s=(3.0, 3.0),
    )
    sizes = []
    for second in range(5000):
        modules.gps_sample(_cruise(float(second), speed_mps=0.0))
        sizes.append(math.hypot(*modules.gps_error_m[:2]))
    jumped = np.array(sizes) > 1.0
    assert_allclose(np.array(sizes)[jumped], 5.0, atol=1e-9)
    starts = np.flatnonzero(jumped[1:] & ~jumped[:-1]) + 1
    # Each event lasts 3 fixes (3 s at 1 Hz); a new one may start right after.
    assert jumped.sum() == 3 * modules.multipath_events
    # 5000 s at 0.02 /s, no new event during one (3 s): about 5000 · 0.02 / 1.06 ≈ 94.
    assert 60 <= modules.multipath_events <= 130
    assert len(starts) <= modules.multipath_events


def test_same_seed_same_datagrams_another_seed_others() -> None:
    def datagrams(seed: int) -> list[bytes]:
        modules = InterfaceModules(RING, rng=np.random.default_rng(seed))
        out = modules.start(_cruise(0.0))
        for tick in range(300):
            out += modules.step(_cruise(tick / 100.0))
        return out

    assert datagrams(21) == datagrams(21)
    assert datagrams(21) != datagrams(22)
