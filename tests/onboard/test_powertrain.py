"""The seed 003 §6 powertrain: Coulomb counting, efficiencies, range extender, BMS limits."""

from __future__ import annotations

import pytest
from numpy.testing import assert_allclose

from onboard.plant.powertrain import (
    BatteryPack,
    BatteryParameters,
    DriveThermalModel,
    Powertrain,
    RangeExtender,
)

PACK = BatteryParameters()


def test_coulomb_counting_matches_the_integral_of_current_over_capacity() -> None:
    pack = BatteryPack(PACK, soc=0.8)
    charge_as = 0.0
    for k in range(600):
        power = 60_000.0 if k < 400 else -30_000.0
        charge_as += pack.step(1.0, power) * 1.0
    assert_allclose(pack.soc, 0.8 - charge_as / (105.0 * 3600.0), atol=1e-12)


def test_discharge_draws_power_over_efficiency_and_charge_stores_efficiency_times_power() -> None:
    pack = BatteryPack(PACK, soc=0.5)
    voltage = pack.open_circuit_voltage_v()
    assert_allclose(voltage, 742.0, atol=1e-9)
    assert_allclose(pack.step(1e-3, 95_000.0), 100_000.0 / voltage, rtol=1e-9)
    voltage = pack.open_circuit_voltage_v()
    assert_allclose(pack.step(1e-3, -100_000.0), -95_000.0 / voltage, rtol=1e-9)
    assert_allclose(pack.energy_out_j, 95.0, atol=1e-9)
    assert_allclose(pack.energy_in_j, 100.0, atol=1e-9)


def test_drive_losses_are_taken_on_the_electrical_side() -> None:
    powertrain = Powertrain()
    assert_allclose(powertrain.drive_electrical_power_w(92_000.0), 100_000.0, rtol=1e-12)
    assert_allclose(powertrain.drive_electrical_power_w(-100_000.0), -92_000.0, rtol=1e-12)


def test_bus_balance_drives_plus_auxiliaries_equal_batteries_plus_range_extender() -> None:
    powertrain = Powertrain(soc=0.7)
    for _ in range(200):
        state = powertrain.step(
            0.1,
            mechanical_power_front_w=40_000.0,
            mechanical_power_rear_w=50_000.0,
            range_extender_reference_w=60_000.0,
        )
    assert_allclose(
        state.drives_power_w + state.auxiliary_power_w,
        state.battery_power_w + state.range_extender_power_w,
        atol=1e-6,
    )
    assert_allclose(state.drives_power_w, 90_000.0 / 0.92, rtol=1e-12)


def test_range_extender_follows_a_first_order_lag_and_stays_within_its_map() -> None:
    range_extender = RangeExtender()
    tau = range_extender.parameters.time_constant_s
    dt = 0.001
    for _ in range(round(tau / dt)):
        range_extender.step(dt, 80_000.0)
    # After one time constant a first-order lag has covered 1 − 1/e of the step.
    assert_allclose(range_extender.power_w, 80_000.0 * (1.0 - 1.0 / 2.718281828), rtol=2e-3)
    for _ in range(60_000):
        range_extender.step(dt, 250_000.0)
    # 60 s is 20 time constants: within e^-20 × 100 kW ≈ 0.2 mW of the target.
    assert_allclose(range_extender.power_w, 100_000.0, atol=1e-3)
    for _ in range(60_000):
        range_extender.step(dt, -50_000.0)
    assert_allclose(range_extender.power_w, 0.0, atol=1e-3)


def test_fuel_follows_the_specific_consumption() -> None:
    range_extender = RangeExtender()
    range_extender.power_w = 75_000.0
    fuel_before = range_extender.fuel_kg
    for _ in range(3600):
        range_extender.step(1.0, 75_000.0)
    # 75 kWh at 235 g/kWh.
    assert_allclose(range_extender.fuel_kg - fuel_before, 17.625, rtol=1e-9)
    assert_allclose(range_extender.specific_consumption_g_per_kwh(62_500.0), 242.5, atol=1e-9)


@pytest.mark.parametrize(
    ("soc", "discharge_a", "charge_a"),
    [(0.5, 200.0, 200.0), (0.125, 100.0, 200.0), (0.05, 0.0, 200.0), (0.925, 200.0, 100.0)],
)
def test_bms_limits_ramp_down_at_the_ends_of_the_soc_window(
    soc: float, discharge_a: float, charge_a: float
) -> None:
    pack = BatteryPack(PACK, soc=soc)
    assert_allclose(pack.max_discharge_current_a(), discharge_a, atol=1e-9)
    assert_allclose(pack.max_charge_current_a(), charge_a, atol=1e-9)
    powertrain = Powertrain(soc=soc)
    status = powertrain.bms_status()
    assert_allclose(status.max_discharge_current_a, 2 * discharge_a, atol=1e-9)
    assert_allclose(
        status.max_discharge_power_w, 2 * discharge_a * status.voltage_v * 0.95, rtol=1e-12
    )


def test_drive_temperature_rises_with_torque_squared_towards_its_steady_state() -> None:
    model = DriveThermalModel()
    for _ in range(20_000):
        model.step(1.0, 6_000.0)
    # 25 °C + 100 K × (6000 / 4000)².
    assert_allclose(model.temperature_c, 250.0, atol=1e-3)


def test_an_soc_outside_zero_to_one_is_refused() -> None:
    with pytest.raises(ValueError, match="SOC"):
        BatteryPack(PACK, soc=1.2)
