"""The seed 003 §3 VCU strategies, each with synthetic inputs."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import pytest
from numpy.testing import assert_allclose

from onboard.plant.interfaces import ActuatorCommands
from onboard.vcu import (
    BrakingPhase,
    EnergyManager,
    Limitation,
    VcuInputs,
    VcuParameters,
    VehicleControlUnit,
)

P = VcuParameters()
RADIUS = P.wheel_radius_m


def moving(speed_mps: float, **changes: Any) -> VcuInputs:
    """Inputs of a vehicle rolling without slip at ``speed_mps``; plenty of power."""
    omega = speed_mps / RADIUS
    base = VcuInputs(
        fused_speed_mps=speed_mps,
        wheel_speed_front_radps=omega,
        wheel_speed_rear_radps=omega,
        soc=0.7,
        range_extender_power_w=100_000.0,
    )
    return replace(base, **changes)


def run(vcu: VehicleControlUnit, inputs: VcuInputs, steps: int = 50) -> ActuatorCommands:
    commands = ActuatorCommands()
    for _ in range(steps):
        commands = vcu.step(0.01, inputs)
    return commands


@pytest.mark.parametrize("direction", [1, -1])
def test_starting_torque_goes_to_the_trailing_axle_alone(direction: int) -> None:
    commands = run(VehicleControlUnit(), moving(0.0, force_demand_n=10_000.0, direction=direction))
    total = 10_000.0 * RADIUS
    trailing, leading = (
        (commands.motor_torque_rear_nm, commands.motor_torque_front_nm)
        if direction > 0
        else (commands.motor_torque_front_nm, commands.motor_torque_rear_nm)
    )
    assert_allclose(trailing, direction * total, atol=1e-9)
    assert_allclose(leading, 0.0, atol=1e-9)


def test_the_leading_axle_takes_what_the_trailing_axle_cannot_carry() -> None:
    commands = run(VehicleControlUnit(), moving(0.0, force_demand_n=20_000.0))
    assert_allclose(commands.motor_torque_rear_nm, P.max_motor_torque_nm, atol=1e-9)
    assert_allclose(commands.motor_torque_front_nm, 20_000.0 * RADIUS - 6_900.0, atol=1e-9)


@pytest.mark.parametrize("direction", [1, -1])
def test_torques_are_equal_above_the_threshold_speed(direction: int) -> None:
    vcu = VehicleControlUnit()
    halfway = run(vcu, moving(4.5, force_demand_n=10_000.0, direction=direction))
    assert abs(halfway.motor_torque_front_nm) != pytest.approx(abs(halfway.motor_torque_rear_nm))
    commands = run(vcu, moving(10.0, force_demand_n=10_000.0, direction=direction))
    assert_allclose(commands.motor_torque_front_nm, direction * 0.5 * 10_000.0 * RADIUS, atol=1e-9)
    assert_allclose(commands.motor_torque_rear_nm, commands.motor_torque_front_nm, atol=1e-9)


def test_slip_cuts_traction_then_restarts_lower_and_ramps_back() -> None:
    vcu = VehicleControlUnit()
    steady = moving(20.0, force_demand_n=20_000.0)
    before = run(vcu, steady)
    per_axle = 0.5 * 20_000.0 * RADIUS
    assert_allclose(before.motor_torque_rear_nm, per_axle, atol=1e-9)
    # The rear axle spins up 2 m/s above the fused speed.
    slipping = replace(steady, wheel_speed_rear_radps=22.0 / RADIUS)
    cut = run(vcu, slipping, steps=10)
    assert vcu.status.slip_rear
    assert not vcu.status.slip_front
    assert_allclose(cut.motor_torque_rear_nm, 0.0, atol=1e-12)
    assert_allclose(cut.motor_torque_front_nm, per_axle, atol=1e-9)
    # Adhesion back: the cut-off lasts slip_cutoff_s, then half the old torque, ramped up.
    held = run(vcu, steady, steps=round(P.slip_cutoff_s / 0.01) - 1)
    assert_allclose(held.motor_torque_rear_nm, 0.0, atol=1e-12)
    restart = run(vcu, steady, steps=2)
    ramp_step = P.slip_recovery_rate_per_s * P.max_motor_torque_nm * 0.01
    assert_allclose(restart.motor_torque_rear_nm, 0.5 * per_axle + ramp_step, atol=1e-6)
    recovered = run(vcu, steady, steps=300)
    assert_allclose(recovered.motor_torque_rear_nm, per_axle, atol=1e-9)
    assert not vcu.status.slip_detected


def test_an_axle_faster_than_the_other_is_a_slip_even_if_the_fused_speed_lags() -> None:
    vcu = VehicleControlUnit()
    run(vcu, moving(20.0, force_demand_n=20_000.0))
    run(vcu, moving(20.0, force_demand_n=20_000.0, wheel_speed_front_radps=21.5 / RADIUS), 2)
    assert vcu.status.slip_front


def test_repeated_slips_declare_the_rail_slippery_and_limit_torque() -> None:
    vcu = VehicleControlUnit()
    steady = moving(2.0, force_demand_n=25_000.0)
    for _ in range(P.slippery_rail_slip_count):
        run(vcu, steady, steps=100)
        run(vcu, replace(steady, wheel_speed_rear_radps=4.0 / RADIUS), steps=5)
    commands = run(vcu, steady, steps=500)
    assert Limitation.SLIPPERY_RAIL in vcu.status.limitations
    limit = P.slippery_rail_torque_fraction * P.max_motor_torque_nm
    assert_allclose(commands.motor_torque_rear_nm, limit, atol=1e-9)


def braking_torques(commands: ActuatorCommands) -> tuple[float, float]:
    electric = -(commands.motor_torque_front_nm + commands.motor_torque_rear_nm)
    pressure = commands.brake_pressure_front_pa + commands.brake_pressure_rear_pa
    return electric, P.brake_gain_nm_per_pa * pressure


@pytest.mark.parametrize(
    ("speed_mps", "phase", "electric_share"),
    [
        (33.0, BrakingPhase.ELECTRIC, 1.0),
        (30.0 / 3.6, BrakingPhase.ELECTRIC, 1.0),
        (20.0 / 3.6, BrakingPhase.BLENDED, 0.5),
        (10.0 / 3.6, BrakingPhase.PNEUMATIC, 0.0),
        (1.0, BrakingPhase.PNEUMATIC, 0.0),
    ],
)
def test_three_braking_phases_by_speed_and_the_sum_meets_the_demand(
    speed_mps: float, phase: BrakingPhase, electric_share: float
) -> None:
    vcu = VehicleControlUnit()
    commands = run(vcu, moving(speed_mps, force_demand_n=-12_000.0))
    demand = 12_000.0 * RADIUS
    electric, pneumatic = braking_torques(commands)
    assert vcu.status.braking_phase is phase
    assert_allclose(electric, electric_share * demand, atol=1e-6)
    assert_allclose(electric + pneumatic, demand, atol=1e-6)


def test_high_soc_reduces_electric_braking_and_the_pneumatic_brake_compensates() -> None:
    vcu = VehicleControlUnit()
    commands = run(vcu, moving(40.0, force_demand_n=-12_000.0, soc=0.93))
    demand = 12_000.0 * RADIUS
    electric, pneumatic = braking_torques(commands)
    # k_e falls linearly from 1 at 90 % to 0 at 95 %: 0.4 at 93 %.
    assert_allclose(electric, 0.4 * demand, atol=1e-6)
    assert_allclose(electric + pneumatic, demand, atol=1e-6)
    assert Limitation.HIGH_SOC in vcu.status.limitations


def test_the_bms_charge_limit_caps_electric_braking_and_the_pneumatic_brake_compensates() -> None:
    vcu = VehicleControlUnit()
    inputs = moving(40.0, force_demand_n=-12_000.0, max_charge_power_w=50_000.0)
    inputs = replace(inputs, range_extender_power_w=0.0)
    commands = run(vcu, inputs)
    electric, pneumatic = braking_torques(commands)
    regen_mechanical_w = (50_000.0 + P.auxiliary_power_w) / P.drive_efficiency
    assert_allclose(electric * 40.0 / RADIUS, regen_mechanical_w, rtol=1e-9)
    assert_allclose(electric + pneumatic, 12_000.0 * RADIUS, atol=1e-6)


def test_motor_temperature_derates_torque_linearly() -> None:
    vcu = VehicleControlUnit()
    commands = run(vcu, moving(10.0, force_demand_n=28_000.0, motor_temperature_rear_c=150.0))
    assert Limitation.TEMPERATURE in vcu.status.limitations
    # Halfway between 140 °C and 160 °C: half the 6900 N·m on the rear axle.
    assert_allclose(commands.motor_torque_rear_nm, 3_450.0, atol=1e-9)
    assert_allclose(commands.motor_torque_front_nm, 6_900.0, atol=1e-9)


def test_battery_overload_holds_the_discharge_to_the_continuous_rating() -> None:
    vcu = VehicleControlUnit()
    overloaded = moving(
        30.0, force_demand_n=28_000.0, battery_current_a=400.0, range_extender_power_w=0.0
    )
    # 0.8 × (400² − 210²) × 60 / (400² − 210²) = 48 s at 400 A.
    run(vcu, overloaded, steps=4_790)
    assert Limitation.BATTERY_OVERLOAD not in vcu.status.limitations
    commands = run(vcu, overloaded, steps=20)
    assert Limitation.BATTERY_OVERLOAD in vcu.status.limitations
    assert vcu.status.range_extender_on
    assert_allclose(commands.range_extender_power_w, P.range_extender_max_power_w, atol=1e-9)
    continuous_w = 210.0 * 742.0 * 0.95
    assert_allclose(
        vcu.status.traction_power_limit_w, continuous_w - P.auxiliary_power_w, rtol=1e-9
    )
    total = commands.motor_torque_front_nm + commands.motor_torque_rear_nm
    mechanical = (continuous_w - P.auxiliary_power_w) * P.drive_efficiency
    assert_allclose(total * 30.0 / RADIUS, mechanical, rtol=1e-9)


def test_low_soc_phases_out_battery_power_and_runs_the_range_extender_at_full_power() -> None:
    vcu = VehicleControlUnit()
    low = moving(
        50.0,
        force_demand_n=10_000.0,
        soc=0.40,
        max_discharge_power_w=200_000.0,
        range_extender_power_w=100_000.0,
    )
    commands = run(vcu, low, steps=100)
    assert Limitation.LOW_SOC in vcu.status.limitations
    assert_allclose(commands.range_extender_power_w, 100_000.0, atol=1e-9)
    # The allowance falls by 500 W/s from 200 kW: 199.5 kW after the first second.
    assert_allclose(vcu.status.traction_power_limit_w, 199_500.0 + 95_000.0, atol=1e-6)
    for _ in range(400):
        vcu.step(1.0, low)
    # Battery allowance gone: the drives get the RE's power less the auxiliaries.
    assert_allclose(vcu.status.traction_power_limit_w, 95_000.0, atol=1e-6)


def test_while_sustaining_the_batteries_lend_only_the_charge_put_back_above_the_threshold() -> None:
    manager = EnergyManager(P)
    continuous = 210.0 * 742.0 * 0.95
    limits: dict[str, Any] = {"bus_load_w": 150_000.0, "max_discharge_w": 290_000.0}
    reference = manager.step(1.0, soc=0.46, continuous_discharge_w=continuous, **limits)
    assert manager.sustaining
    assert_allclose(reference, P.range_extender_max_power_w, atol=1e-9)
    # Under the threshold the allowance phases out to zero at 500 W/s...
    for _ in range(600):
        manager.step(1.0, soc=0.46, continuous_discharge_w=continuous, **limits)
    assert_allclose(manager.battery_allowance_w, 0.0, atol=1e-9)
    # ... above it the packs lend up to their continuous rating, ramped over the band.
    above = P.sustaining_soc_on + P.sustaining_buffer_band
    for soc, share in ((above + 0.01, 1.0), (P.sustaining_soc_on + 0.0025, 0.5), (0.465, 0.0)):
        manager.step(1.0, soc=soc, continuous_discharge_w=continuous, **limits)
        assert manager.sustaining
        assert_allclose(manager.battery_allowance_w, share * continuous, rtol=1e-9, atol=1e-6)


def test_range_extender_switches_on_soc_with_hysteresis() -> None:
    manager = EnergyManager(P)
    load = 10_000.0
    states = []
    for soc in (0.50, 0.47, 0.46, 0.48, 0.499, 0.51, 0.48):
        reference = manager.step(1.0, soc=soc, bus_load_w=load, max_discharge_w=290_000.0)
        states.append((manager.range_extender_on, reference))
    assert [on for on, _ in states] == [False, False, True, True, True, False, False]
    assert_allclose(states[2][1], 100_000.0, atol=1e-9)


def test_range_extender_switches_on_load_with_hysteresis_and_covers_the_excess() -> None:
    manager = EnergyManager(P)
    share = P.battery_share_w
    ons = []
    for load in (share + 20_000.0, share + 30_000.0, share + 15_000.0, share + 5_000.0):
        reference = manager.step(1.0, soc=0.8, bus_load_w=load, max_discharge_w=290_000.0)
        ons.append(manager.range_extender_on)
        if manager.range_extender_on:
            assert_allclose(reference, load - share, atol=1e-9)
    assert ons == [False, True, True, False]


def test_speed_reference_is_tracked_by_the_internal_loop() -> None:
    vcu = VehicleControlUnit()
    run(vcu, moving(20.0, speed_reference_mps=25.0), steps=1)
    assert vcu.status.force_demand_n > 0.0
    run(vcu, moving(30.0, speed_reference_mps=25.0), steps=200)
    assert vcu.status.force_demand_n < 0.0
