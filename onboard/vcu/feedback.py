"""What the VCU reads back from the vehicle, and what it must know of the vehicle's hardware.

Used wherever the VCU runs in closed loop with the bogie model and the powertrain: the onboard
process's bogie-fidelity vehicle (:mod:`onboard.vcu.vehicle`) and the seed 003 benches
(``deploy.bench``).

- :func:`vcu_parameters_for`: VCU parameters whose plant constants are the bogie's.
- :func:`powertrain_feedback`: the BMS, range-extender and drive-temperature signals.
- :func:`vcu_inputs`: the demand, the speeds and that feedback, as over the VCU's buses.
- :func:`step_powertrain`: the powertrain fed with the drives' actual mechanical powers.
"""

from __future__ import annotations

import dataclasses

from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS, BogieParameters
from onboard.plant.interfaces import BogieTruth
from onboard.plant.powertrain import Powertrain
from onboard.vcu.parameters import VcuInputs, VcuParameters

__all__ = ["powertrain_feedback", "step_powertrain", "vcu_inputs", "vcu_parameters_for"]


def vcu_parameters_for(
    bogie: BogieParameters = URV_BOGIE_PARAMETERS, base: VcuParameters | None = None
) -> VcuParameters:
    """VCU parameters whose plant constants are the bogie's: wheel radius [m], motor torque
    [N·m] and power [W] per wheelset, brake gain [N·m/Pa] and maximum pressure [Pa].

    The VCU's defaults assume 6.9e-3 N·m/Pa up to 5 bar; the bogie's brakes give 1.035e-2 N·m/Pa
    up to 4 bar, so without this the VCU's pressures would brake half as hard again as meant.
    """
    return dataclasses.replace(
        base if base is not None else VcuParameters(),
        wheel_radius_m=bogie.wheel_radius_m,
        max_motor_torque_nm=bogie.motor_max_torque_nm,
        max_motor_power_w=bogie.motor_max_power_w,
        brake_gain_nm_per_pa=bogie.brake_gain_m3,
        max_brake_pressure_pa=bogie.brake_max_pressure_pa,
    )


def powertrain_feedback(powertrain: Powertrain, demand: VcuInputs) -> VcuInputs:
    """``demand`` (the ADF's demand and the speeds) completed with what the VCU reads from the
    BMS, the range extender and the drives' temperatures."""
    bms = powertrain.bms_status()
    return dataclasses.replace(
        demand,
        soc=bms.soc,
        battery_current_a=bms.current_a,
        battery_voltage_v=bms.voltage_v,
        max_discharge_power_w=bms.max_discharge_power_w,
        max_charge_power_w=bms.max_charge_power_w,
        continuous_current_a=bms.continuous_current_a,
        range_extender_power_w=powertrain.range_extender.power_w,
        motor_temperature_front_c=powertrain.thermal_front.temperature_c,
        motor_temperature_rear_c=powertrain.thermal_rear.temperature_c,
    )


def vcu_inputs(
    direction: int, truth: BogieTruth, fused_mps: float, force_n: float, pt: Powertrain
) -> VcuInputs:
    """What the VCU reads over its buses: the demand, speeds, the BMS and the drives."""
    return powertrain_feedback(
        pt,
        VcuInputs(
            force_demand_n=force_n,
            direction=direction,
            fused_speed_mps=fused_mps,
            wheel_speed_front_radps=abs(truth.wheel_speed_front_radps),
            wheel_speed_rear_radps=abs(truth.wheel_speed_rear_radps),
        ),
    )


def step_powertrain(pt: Powertrain, dt_s: float, truth: BogieTruth, re_w: float) -> None:
    """Feed the powertrain the drives' actual mechanical powers and the RE reference [W]."""
    pt.step(
        dt_s,
        mechanical_power_front_w=truth.motor_torque_front_nm * truth.wheel_speed_front_radps,
        mechanical_power_rear_w=truth.motor_torque_rear_nm * truth.wheel_speed_rear_radps,
        range_extender_reference_w=re_w,
        motor_torque_front_nm=truth.motor_torque_front_nm,
        motor_torque_rear_nm=truth.motor_torque_rear_nm,
    )
