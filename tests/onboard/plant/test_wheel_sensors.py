"""The axle sensors: the diameter error's draw and scale, integration, slip on the bogie model,
and the pulse counter's quantisation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from onboard.plant.bogie import BogieModel
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS
from onboard.plant.interfaces import ActuatorCommands, BogieTruth
from onboard.plant.sensors import TruthSample
from onboard.plant.wheel_sensors import (
    DIAMETER_ERROR_SIGMA,
    PulseCounter,
    WheelSensors,
    draw_diameter_error,
)

DT_S = 0.01


def _bogie_truth(time_s: float, front_radps: float, rear_radps: float) -> BogieTruth:
    return BogieTruth(
        time_s=time_s,
        position_m=0.0,
        speed_mps=0.0,
        acceleration_mps2=0.0,
        wheel_speed_front_radps=front_radps,
        wheel_speed_rear_radps=rear_radps,
        wheel_radius_m=0.46,
        motor_torque_front_nm=0.0,
        motor_torque_rear_nm=0.0,
        brake_torque_front_nm=0.0,
        brake_torque_rear_nm=0.0,
        normal_force_front_n=0.0,
        normal_force_rear_n=0.0,
        creepage_front=0.0,
        creepage_rear=0.0,
        traction_energy_j=0.0,
        regen_energy_j=0.0,
    )


def test_a_worn_wheel_reads_long_on_the_point_mass_model() -> None:
    wheels = WheelSensors(rng=np.random.default_rng(0), diameter_error=0.02)
    readings = [
        wheels.step(
            TruthSample(
                time_s=k * DT_S,
                position_m=250.0 + 10.0 * k * DT_S,
                speed_mps=10.0,
                acceleration_mps2=0.0,
            )
        )
        for k in range(1001)
    ]
    last = readings[-1]
    assert readings[0].travel_front_m == 0.0
    assert_allclose(last.travel_front_m, 1.02 * 100.0, atol=1e-9)
    assert last.travel_rear_m == last.travel_front_m
    assert_allclose(last.speed_front_mps, 10.2, atol=1e-12)
    assert last.time_s == pytest.approx(10.0)


def test_each_wheel_is_integrated_trapezoidally_on_the_bogie_model() -> None:
    wheels = WheelSensors(rng=np.random.default_rng(0), diameter_error=-0.01)
    # Front wheel accelerating uniformly from 0 to 20 rad/s over 2 s, rear at a steady 10 rad/s.
    for k in range(201):
        reading = wheels.step(_bogie_truth(k * DT_S, 10.0 * k * DT_S, 10.0))
    assert_allclose(reading.travel_front_m, 0.99 * 0.46 * 20.0, atol=1e-9)
    assert_allclose(reading.travel_rear_m, 0.99 * 0.46 * 20.0, atol=1e-9)
    assert_allclose(reading.speed_front_mps, 0.99 * 0.46 * 20.0, atol=1e-12)


def test_slip_shows_on_the_bogie_models_wheels() -> None:
    parameters = URV_BOGIE_PARAMETERS
    model = BogieModel(speed_mps=20.0)
    wheels = WheelSensors(rng=np.random.default_rng(0), diameter_error=0.0)
    full = ActuatorCommands(
        motor_torque_front_nm=parameters.motor_max_torque_nm,
        motor_torque_rear_nm=parameters.motor_max_torque_nm,
    )
    start = wheels.step(model.truth())
    start_m = model.truth().position_m
    for _ in range(100):  # dry: the wheels follow the vehicle
        model.step(DT_S, full)
        dry = wheels.step(model.truth())
    dry_body_m = model.truth().position_m - start_m
    assert dry.travel_front_m - start.travel_front_m == pytest.approx(dry_body_m, rel=0.01)
    for _ in range(100):  # a slippery rail: the wheels spin up
        model.step(DT_S, full, adhesion_factor=0.15)
        slipping = wheels.step(model.truth())
    truth = model.truth()
    body_m = truth.position_m - start_m
    for travel_m, speed_mps in (
        (slipping.travel_front_m, slipping.speed_front_mps),
        (slipping.travel_rear_m, slipping.speed_rear_mps),
    ):
        assert speed_mps - truth.speed_mps > 1.0
        assert travel_m - body_m > 0.5


def test_the_drawn_diameter_error_has_its_sigma_and_bound() -> None:
    errors = np.array([draw_diameter_error(np.random.default_rng(seed)) for seed in range(4000)])
    # A normal truncated at ±3 σ has σ 0.9866 of the untruncated one.
    assert errors.std() == pytest.approx(0.9866 * DIAMETER_ERROR_SIGMA, rel=0.05)
    assert abs(errors.mean()) < 3.0 * DIAMETER_ERROR_SIGMA / math.sqrt(errors.size)
    assert np.abs(errors).max() <= 3.0 * DIAMETER_ERROR_SIGMA
    assert draw_diameter_error(np.random.default_rng(1), 0.0) == 0.0


def test_same_seed_same_wheel_different_seed_another() -> None:
    def error(seed: int) -> float:
        return WheelSensors(rng=np.random.default_rng(seed)).diameter_error

    assert error(5) == error(5)
    assert error(5) != error(6)
    with pytest.raises(ValueError, match="above -1"):
        WheelSensors(rng=np.random.default_rng(0), diameter_error=-1.0)


def test_pulse_counts_quantise_the_speed_without_losing_travel() -> None:
    count_m, period_s, speed_mps = 0.0036, 0.05, 7.3
    counter = PulseCounter(count_m)
    resolution = count_m / period_s
    speeds = [
        counter.speed(speed_mps * k * period_s, speed_mps, k * period_s, period_s)
        for k in range(400)
    ]
    # Every sample is a whole number of counts over the interval, within one count of the truth.
    counts = np.array(speeds) / resolution
    assert_allclose(counts, np.round(counts), atol=1e-6)
    assert np.abs(np.array(speeds) - speed_mps).max() <= resolution + 1e-9
    # The counts are never lost: the speeds add up to the travel, to within one count.
    travel_m = sum(speeds[1:]) * period_s
    assert travel_m == pytest.approx(speed_mps * 399 * period_s, abs=count_m)
    assert PulseCounter(0.0).speed(1.0, 7.3, 0.0, period_s) == 7.3
