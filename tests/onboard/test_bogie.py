"""Physics of the 10-DOF bogie model (seed 003 §5) and its integrator's verification."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from onboard.plant.bogie import BogieModel
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS
from onboard.plant.contact import longitudinal_creep_force
from onboard.plant.interfaces import ActuatorCommands
from onboard.plant.point_mass import GRAVITY_MPS2, URV_PARAMETERS, PointMassModel

pytestmark = pytest.mark.scenario

P = URV_BOGIE_PARAMETERS
WEIGHT_N = P.total_mass_kg * GRAVITY_MPS2
FULL_TORQUE = ActuatorCommands(
    motor_torque_front_nm=P.motor_max_torque_nm, motor_torque_rear_nm=P.motor_max_torque_nm
)
FULL_BRAKE = ActuatorCommands(
    brake_pressure_front_pa=P.brake_max_pressure_pa, brake_pressure_rear_pa=P.brake_max_pressure_pa
)
COAST = ActuatorCommands()
DT_S = 0.01


def _centre_of_gravity_height_m() -> float:
    """Height of the vehicle's centre of gravity above the rail [m]."""
    axle = P.wheel_radius_m
    bogie = axle + P.bogie_centre_above_axle_m
    carbody = bogie + P.pin_above_bogie_centre_m + P.carbody_centre_above_pin_m
    moment = 2 * P.wheelset_mass_kg * axle + P.bogie_mass_kg * bogie + P.carbody_mass_kg * carbody
    return moment / P.total_mass_kg


def _run(model: BogieModel, seconds: float, commands: ActuatorCommands, **kwargs: float) -> None:
    for _ in range(round(seconds / DT_S)):
        model.step(DT_S, commands, **kwargs)


def test_mass_matches_point_mass_model() -> None:
    assert_allclose(P.total_mass_kg, URV_PARAMETERS.mass_kg, rtol=1e-12)
    rotating = 2 * P.wheelset_spin_inertia_kgm2 / P.wheel_radius_m**2 / P.total_mass_kg
    assert_allclose(rotating, URV_PARAMETERS.rotating_mass_factor, rtol=1e-12)
    assert_allclose(
        2 * P.motor_max_torque_nm / P.wheel_radius_m, URV_PARAMETERS.max_traction_force_n
    )


def test_static_equilibrium_on_level_track() -> None:
    model = BogieModel()
    _run(model, 2.0, COAST)
    truth = model.truth()
    assert_allclose(truth.normal_force_front_n + truth.normal_force_rear_n, WEIGHT_N, rtol=1e-9)
    assert_allclose(truth.normal_force_front_n, truth.normal_force_rear_n, atol=1e-3)
    assert abs(truth.position_m) < 1e-9
    assert abs(truth.speed_mps) < 1e-9


@pytest.mark.parametrize("gradient_permille", [25.0, -25.0])
def test_load_transfer_on_gradient(gradient_permille: float) -> None:
    """Held by its brakes, the vehicle loads its downhill axle by m g sin α h / wheelbase."""
    model = BogieModel()
    _run(model, 3.0, FULL_BRAKE, gradient_permille=gradient_permille)
    truth = model.truth()
    angle = math.atan(gradient_permille / 1000.0)
    assert_allclose(
        truth.normal_force_front_n + truth.normal_force_rear_n,
        WEIGHT_N * math.cos(angle),
        rtol=1e-6,
    )
    transfer = WEIGHT_N * math.sin(angle) * _centre_of_gravity_height_m() / (2 * P.half_wheelbase_m)
    # Uphill (positive gradient) the rear axle is the downhill one and carries more.
    assert_allclose(truth.normal_force_rear_n - truth.normal_force_front_n, 2 * transfer, rtol=0.02)


def test_load_transfer_under_traction() -> None:
    """Accelerating unloads the front axle by about F h / wheelbase."""
    model = BogieModel(speed_mps=10.0)
    _run(model, 2.0, FULL_TORQUE)
    truth = model.truth()
    force_n = (truth.motor_torque_front_nm + truth.motor_torque_rear_nm) / P.wheel_radius_m
    transfer = force_n * _centre_of_gravity_height_m() / (2 * P.half_wheelbase_m)
    assert truth.normal_force_rear_n > truth.normal_force_front_n
    # Not exact: part of the tractive force turns the wheels and the axles sit lower.
    assert_allclose(truth.normal_force_rear_n - truth.normal_force_front_n, 2 * transfer, rtol=0.1)
    assert_allclose(truth.normal_force_front_n + truth.normal_force_rear_n, WEIGHT_N, rtol=1e-3)


def test_coasting_decelerates_as_the_davis_resistance_predicts() -> None:
    start_mps = 50.0
    model = BogieModel(speed_mps=start_mps)
    _run(model, 0.5, COAST)  # let the initial transient of the suspension settle
    speed_before = model.truth().speed_mps
    seconds = 10.0
    _run(model, seconds, COAST)
    speed_after = model.truth().speed_mps
    deceleration = (speed_before - speed_after) / seconds
    point_mass = PointMassModel()
    mean_mps = 0.5 * (speed_before + speed_after)
    expected = point_mass.resistance_n(mean_mps, 0.0, math.inf) / (
        URV_PARAMETERS.mass_kg * (1 + URV_PARAMETERS.rotating_mass_factor)
    )
    # The lift unloads the wheels a little, so the rolling resistance is slightly lower.
    assert_allclose(deceleration, expected, rtol=0.02)


def test_energy_balance_closes_over_a_manoeuvre() -> None:
    """Motor work = Δ kinetic + Δ elastic − gravity work + losses, within 1 %."""
    model = BogieModel()
    _run(model, 20.0, FULL_TORQUE, gradient_permille=10.0)
    regen = ActuatorCommands(
        motor_torque_front_nm=-0.5 * P.motor_max_torque_nm,
        motor_torque_rear_nm=-0.5 * P.motor_max_torque_nm,
        brake_pressure_front_pa=1.0e5,
        brake_pressure_rear_pa=1.0e5,
    )
    _run(model, 10.0, regen, gradient_permille=-5.0)
    energy = model.energy()
    truth = model.truth()
    assert truth.traction_energy_j > 1e6
    assert truth.regen_energy_j > 1e5
    for loss in (energy.damping_j, energy.creep_j, energy.rolling_j, energy.brake_j):
        assert loss > 0.0
    assert energy.aerodynamic_j > 0.0
    assert abs(energy.residual_j()) < 0.01 * truth.traction_energy_j


def test_brakes_hold_a_standstill_on_a_gradient() -> None:
    braked = BogieModel()
    _run(braked, 30.0, FULL_BRAKE, gradient_permille=25.0)
    assert abs(braked.truth().position_m) < 0.01
    assert abs(braked.truth().speed_mps) < 1e-3
    free = BogieModel()
    _run(free, 10.0, COAST, gradient_permille=25.0)
    assert free.truth().speed_mps < -1.0  # without brakes it rolls back down


def test_wheels_slip_when_torque_exceeds_adhesion() -> None:
    model = BogieModel(speed_mps=20.0)
    _run(model, 1.0, FULL_TORQUE)
    dry = model.truth()
    assert abs(dry.creepage_front) < 0.005
    assert abs(dry.creepage_rear) < 0.005
    assert abs(dry.wheel_speed_front_radps * P.wheel_radius_m - dry.speed_mps) < 0.1
    _run(model, 1.0, FULL_TORQUE, adhesion_factor=0.15)
    slippery = model.truth()
    for creep, wheel in (
        (slippery.creepage_front, slippery.wheel_speed_front_radps),
        (slippery.creepage_rear, slippery.wheel_speed_rear_radps),
    ):
        assert creep < -0.05
        assert wheel * P.wheel_radius_m - slippery.speed_mps > 1.0
    # The vehicle still accelerates, by the little adhesion left.
    assert 0.0 < slippery.acceleration_mps2 < 0.5 * dry.acceleration_mps2


def test_motor_torque_follows_its_lag_and_the_power_limit() -> None:
    model = BogieModel(speed_mps=50.0)
    _run(model, P.motor_time_constant_s, FULL_TORQUE)
    truth = model.truth()
    power_limit = P.motor_max_power_w / truth.wheel_speed_front_radps
    assert power_limit < P.motor_max_torque_nm * (1 - math.exp(-1.0))
    assert_allclose(truth.motor_torque_front_nm, power_limit, rtol=1e-9)


def test_brake_pressure_follows_its_lag() -> None:
    model = BogieModel(speed_mps=30.0)
    _run(model, P.brake_time_constant_s, FULL_BRAKE)
    truth = model.truth()
    expected = -P.brake_gain_m3 * P.brake_max_pressure_pa * (1 - math.exp(-1.0))
    assert_allclose(truth.brake_torque_front_nm, expected, rtol=1e-9)
    assert_allclose(truth.brake_torque_rear_nm, expected, rtol=1e-9)


def test_creep_force_slope_matches_finite_differences() -> None:
    for slip in (-0.5, -0.01, -1e-4, 1e-3, 0.2):
        _, slope = longitudinal_creep_force(slip, 30.0, 7e4, P.contact, 0.6)
        step = 1e-7
        plus, _ = longitudinal_creep_force(slip + step, 30.0, 7e4, P.contact, 0.6)
        minus, _ = longitudinal_creep_force(slip - step, 30.0, 7e4, P.contact, 0.6)
        assert_allclose(slope, (plus - minus) / (2 * step), rtol=1e-5)


def _verification_manoeuvre(model: BogieModel) -> np.ndarray:
    """2 s at full torque then 2 s of blended braking, on a 5 ‰ climb, logged every 10 ms."""
    brake = ActuatorCommands(
        motor_torque_front_nm=-2000.0,
        motor_torque_rear_nm=-2000.0,
        brake_pressure_front_pa=3.0e5,
        brake_pressure_rear_pa=3.0e5,
    )
    log = []
    for index in range(400):
        model.step(DT_S, FULL_TORQUE if index < 200 else brake, gradient_permille=5.0)
        truth = model.truth()
        log.append(
            (
                truth.position_m,
                truth.speed_mps,
                truth.wheel_speed_front_radps,
                truth.wheel_speed_rear_radps,
                truth.normal_force_front_n,
            )
        )
    return np.array(log)


def test_linearly_implicit_scheme_agrees_with_forward_euler_reference() -> None:
    """The seed's forward Euler at 1e-4 s against the default scheme at 2 ms, same manoeuvre.

    The reference starts at 15 m/s: below about 2 m/s the creep force makes forward Euler at
    1e-4 s unstable with these parameters.
    """
    reference = _verification_manoeuvre(
        BogieModel(speed_mps=15.0, integrator="forward_euler", max_substep_s=1e-4)
    )
    fast = _verification_manoeuvre(BogieModel(speed_mps=15.0, max_substep_s=2e-3))
    error = np.abs(fast - reference).max(axis=0)
    assert error[0] < 0.01  # position [m]
    assert error[1] < 0.005  # speed [m/s]
    assert error[2] < 0.02  # front wheel speed [rad/s]
    assert error[3] < 0.02  # rear wheel speed [rad/s]
    assert error[4] < 500.0  # front normal force [N]


def test_the_compiled_creep_force_is_contacts_formula_bit_for_bit() -> None:
    """The bogie's compiled substeps run contact.polach_force compiled: the same bits as the
    interpreter's (no fast-math, no fused multiply-add), over the slip, speed and load seen."""
    from onboard.plant.bogie_kernel import _polach
    from onboard.plant.contact import polach_force

    c = P.contact
    rng = np.random.default_rng(24)
    for _ in range(2000):
        slip = float(rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-9.0, 1.0))
        speed = float(rng.uniform(-40.0, 40.0))
        normal = float(rng.uniform(-1e4, 1.5e5))
        friction = float(c.static_friction * rng.uniform(0.1, 1.0))
        constants = (
            friction,
            c.friction_ratio_at_infinite_slip,
            c.friction_decay_s_per_m,
            c.creep_coefficient_n,
            c.reduction_adhesion_area,
            c.reduction_slip_area,
        )
        assert _polach(slip, speed, normal, *constants) == polach_force(
            slip, speed, normal, *constants
        )


_INTERPRETED_RUN = """
import json
from onboard.plant.bogie import BogieModel
from onboard.plant.interfaces import ActuatorCommands
model = BogieModel(speed_mps=8.0)
commands = ActuatorCommands(
    motor_torque_front_nm=900.0, motor_torque_rear_nm=900.0, brake_pressure_rear_pa=1.0e5
)
for _ in range(60):
    model.step(0.01, commands, gradient_permille=-4.0, adhesion_factor=0.7)
print(json.dumps([model.truth().speed_mps, model.truth().wheel_speed_front_radps,
                  model.truth().normal_force_rear_n, model.energy().residual_j()]))
"""


def test_the_compiled_step_is_the_interpreters() -> None:
    """With NUMBA_DISABLE_JIT=1 the kernel's same functions run in the interpreter: a debugging
    aid that must give the compiled step's result (up to the solve's LAPACK build)."""
    import json
    import os
    import subprocess
    import sys

    model = BogieModel(speed_mps=8.0)
    commands = ActuatorCommands(
        motor_torque_front_nm=900.0, motor_torque_rear_nm=900.0, brake_pressure_rear_pa=1.0e5
    )
    for _ in range(60):
        model.step(0.01, commands, gradient_permille=-4.0, adhesion_factor=0.7)
    truth = model.truth()
    compiled = [
        truth.speed_mps,
        truth.wheel_speed_front_radps,
        truth.normal_force_rear_n,
        model.energy().residual_j(),
    ]
    result = subprocess.run(
        [sys.executable, "-c", _INTERPRETED_RUN],
        env={**os.environ, "NUMBA_DISABLE_JIT": "1"},
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    interpreted = json.loads(result.stdout)
    assert_allclose(interpreted[:3], compiled[:3], rtol=1e-10)
    assert abs(interpreted[3] - compiled[3]) < 1e-3
