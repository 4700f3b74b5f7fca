"""The VCU in closed loop with the plant for the seed 003 benches: what the VCU reads, taken
straight from the truth.

The onboard process gives its VCU the sensors' readings (:mod:`onboard.vcu.drive`); the
benches of seed 003 (:mod:`deploy.bench.vcu_mission`, :mod:`deploy.bench.vcu_manoeuvres`)
reproduce the seed's figures with the VCU on ideal measurements, as the seed does, and feed the
powertrain from the bogie model's truth. They live here, off the train.
"""

from __future__ import annotations

import dataclasses

from onboard.plant.interfaces import BogieTruth
from onboard.plant.powertrain import Powertrain
from onboard.vcu.parameters import VcuInputs

__all__ = ["powertrain_feedback", "step_powertrain", "vcu_inputs"]


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
