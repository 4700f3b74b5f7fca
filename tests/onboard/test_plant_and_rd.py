"""Point-mass plant physics and the remote-driving controller in closed loop."""

from __future__ import annotations

import math

import pytest

from onboard.adf import RemoteDrivingController, RemoteDrivingGains
from onboard.plant import URV_PARAMETERS, PointMassModel
from onboard.plant.point_mass import GRAVITY_MPS2

P = URV_PARAMETERS
M_EFF = P.mass_kg * (1 + P.rotating_mass_factor)


def _settle(model: PointMassModel, force: float, seconds: float, dt_s: float = 0.01) -> None:
    for _ in range(round(seconds / dt_s)):
        model.step(dt_s, force)


def test_starting_acceleration_is_force_over_effective_mass() -> None:
    model = PointMassModel()
    model.applied_force_n = 10_000.0  # actuator already at the demand
    model.step(0.001, 10_000.0)
    expected = (10_000.0 - P.davis_a_n) / M_EFF
    assert model.acceleration_mps2 == pytest.approx(expected, rel=1e-9)


def test_traction_envelope() -> None:
    model = PointMassModel()
    assert model.force_limits_n(0.0) == (-P.max_brake_force_n, P.max_traction_force_n)
    low, high = model.force_limits_n(50.0)
    assert high == pytest.approx(P.max_traction_power_w / 50.0)


def test_resistance_terms() -> None:
    model = PointMassModel()
    v = 20.0
    davis = P.davis_a_n + P.davis_b_n_per_mps * v + P.davis_c_n_per_mps2 * v**2
    assert model.resistance_n(v, 0.0, math.inf) == pytest.approx(davis)
    grade = P.mass_kg * GRAVITY_MPS2 * math.sin(math.atan(0.010))
    assert model.resistance_n(v, 10.0, math.inf) == pytest.approx(davis + grade)
    curve = P.mass_kg * GRAVITY_MPS2 * 800.0 / 400.0 / 1000.0
    assert model.resistance_n(v, 0.0, 400.0) == pytest.approx(davis + curve)


def test_constant_force_reaches_the_balancing_speed() -> None:
    model = PointMassModel()
    force = 1_000.0
    _settle(model, force, 6000.0, dt_s=0.05)  # time constant M / (dF/dv) ≈ 440 s
    balance = (
        P.davis_a_n
        + P.davis_b_n_per_mps * model.speed_mps
        + P.davis_c_n_per_mps2 * model.speed_mps**2
    )
    assert balance == pytest.approx(force, rel=1e-3)


def test_braking_stops_and_holds_the_vehicle() -> None:
    model = PointMassModel(speed_mps=10.0)
    _settle(model, -P.max_brake_force_n, 30.0)
    assert model.speed_mps == 0.0
    position = model.position_m
    for _ in range(100):
        model.step(0.01, 0.0, gradient_permille=20.0)  # uphill, no traction: held, no roll-back
    assert model.speed_mps == 0.0
    assert model.position_m == position


def test_rd_controller_tracks_a_target_speed_uphill() -> None:
    model = PointMassModel()
    controller = RemoteDrivingController(
        mass_kg=P.mass_kg, rolling_coefficient=P.davis_a_n / (P.mass_kg * GRAVITY_MPS2)
    )
    target = 30 / 3.6
    demand = 0.0
    for step in range(12_000):  # 120 s at 10 ms, controller at 100 ms
        if step % 10 == 0:
            demand = controller.step(
                0.1,
                target_speed_mps=target,
                speed_mps=model.speed_mps,
                gradient_permille=4.0,
                force_limits_n=model.force_limits_n(model.speed_mps),
            )
        model.step(0.01, demand, gradient_permille=4.0)
    assert model.speed_mps == pytest.approx(target, abs=0.05)


@pytest.mark.parametrize("band_mps", [0.5, math.inf])
def test_a_power_limited_climb_to_the_target_does_not_overshoot(band_mps: float) -> None:
    """From 100 to 200 km/h the URV's 400 kW cannot follow the 0.5 m/s² ramp: the lag it
    builds must not be integrated (without the band it comes out as a 2 km/h overshoot)."""
    model = PointMassModel(speed_mps=100 / 3.6)
    controller = RemoteDrivingController(
        mass_kg=P.mass_kg,
        rolling_coefficient=P.davis_a_n / (P.mass_kg * GRAVITY_MPS2),
        gains=RemoteDrivingGains(integration_band_mps=band_mps),
    )
    controller.reset(model.speed_mps)
    target, top, demand = 200 / 3.6, 0.0, 0.0
    for step in range(30_000):  # 300 s at 10 ms, controller at 200 ms
        if step % 20 == 0:
            demand = controller.step(
                0.2,
                target_speed_mps=target,
                speed_mps=model.speed_mps,
                gradient_permille=0.0,
                force_limits_n=model.force_limits_n(model.speed_mps),
            )
        model.step(0.01, demand)
        top = max(top, model.speed_mps)
    assert model.speed_mps == pytest.approx(target, abs=0.01)
    overshoot_kmh = (top - target) * 3.6
    if math.isfinite(band_mps):
        assert overshoot_kmh < 0.05
    else:
        assert overshoot_kmh > 1.0


def test_rd_controller_brings_the_vehicle_to_a_stop() -> None:
    model = PointMassModel(speed_mps=8.0)
    controller = RemoteDrivingController(mass_kg=P.mass_kg, rolling_coefficient=0.002)
    controller.reset(8.0)
    demand = 0.0
    for step in range(6_000):
        if step % 10 == 0:
            demand = controller.step(
                0.1,
                target_speed_mps=0.0,
                speed_mps=model.speed_mps,
                gradient_permille=0.0,
                force_limits_n=model.force_limits_n(model.speed_mps),
            )
        model.step(0.01, demand)
    assert model.speed_mps == 0.0


def test_gain_table_interpolates_and_holds_at_the_ends() -> None:
    from onboard.adf.rd_controller import GainPoint, RemoteDrivingGains

    gains = RemoteDrivingGains(
        table=(GainPoint(0.0, 100.0, 10.0), GainPoint(10.0, 50.0, 30.0, 2.0))
    )
    assert gains.at(-1.0) == (100.0, 10.0, 0.0)
    assert gains.at(5.0) == pytest.approx((75.0, 20.0, 1.0))
    assert gains.at(99.0) == (50.0, 30.0, 2.0)


def test_align_gives_a_bumpless_start() -> None:
    controller = RemoteDrivingController(mass_kg=P.mass_kg, rolling_coefficient=0.002)
    controller.align(7_500.0, speed_mps=12.0, gradient_permille=3.0)
    first = controller.step(
        0.1,
        target_speed_mps=12.0,
        speed_mps=12.0,
        gradient_permille=3.0,
        force_limits_n=(-15_000.0, 30_000.0),
    )
    assert first == pytest.approx(7_500.0, abs=1.0)
