"""The VCU as fitted to the bogie-fidelity vehicle: the ADF's force demand to actuator commands.

At each plant tick the VCU reads what a real VCU reads over its buses (seed 003 fig. 10): the
force demand of the ADF, the fused speed of the sensor fusion (the vehicle's speed over ground
as the onboard estimates it), the wheel-speed channels of both axles (the axle-end sensors:
slip and slide show in them against the fused speed), and the reports of the battery management
systems, the range extender and the drives' temperature sensors. It answers with the
:class:`~onboard.plant.interfaces.ActuatorCommands` the plant obeys. It never reads the plant.
"""

from __future__ import annotations

from onboard.plant.interfaces import ActuatorCommands
from onboard.plant.readings import PowertrainReading, WheelReading
from onboard.vcu.parameters import VcuInputs, VcuParameters, VcuStatus
from onboard.vcu.unit import VehicleControlUnit

__all__ = ["FORWARD", "VcuDrive", "inputs_from_readings"]

FORWARD = 1
"""The inspection vehicle runs forwards (the direction of increasing chainage)."""


def inputs_from_readings(
    force_demand_n: float,
    *,
    fused_speed_mps: float,
    wheels: WheelReading,
    powertrain: PowertrainReading,
    wheel_radius_m: float,
) -> VcuInputs:
    """What the VCU reads over its buses, from the sensors' readings.

    The wheel-speed channels give each axle's speed at the calibrated radius [m/s]; the VCU
    works in rad/s at its own (the same calibrated) ``wheel_radius_m``.
    """
    return VcuInputs(
        force_demand_n=force_demand_n,
        direction=FORWARD,
        fused_speed_mps=max(fused_speed_mps, 0.0),
        wheel_speed_front_radps=abs(wheels.speed_front_mps) / wheel_radius_m,
        wheel_speed_rear_radps=abs(wheels.speed_rear_mps) / wheel_radius_m,
        soc=powertrain.soc,
        battery_current_a=powertrain.battery_current_a,
        battery_voltage_v=powertrain.battery_voltage_v,
        max_discharge_power_w=powertrain.max_discharge_power_w,
        max_charge_power_w=powertrain.max_charge_power_w,
        continuous_current_a=powertrain.continuous_current_a,
        range_extender_power_w=powertrain.range_extender_power_w,
        motor_temperature_front_c=powertrain.motor_temperature_front_c,
        motor_temperature_rear_c=powertrain.motor_temperature_rear_c,
    )


class VcuDrive:
    """The vehicle's VCU, stepped by the node with the readings of the last plant tick."""

    def __init__(self, parameters: VcuParameters) -> None:
        self.parameters = parameters
        self.unit = VehicleControlUnit(parameters)
        self.inputs = VcuInputs()

    def step(
        self,
        dt_s: float,
        force_demand_n: float,
        *,
        fused_speed_mps: float,
        wheels: WheelReading,
        powertrain: PowertrainReading,
    ) -> ActuatorCommands:
        """Advance by ``dt_s`` [s]: the actuator commands until the next step."""
        self.inputs = inputs_from_readings(
            force_demand_n,
            fused_speed_mps=fused_speed_mps,
            wheels=wheels,
            powertrain=powertrain,
            wheel_radius_m=self.parameters.wheel_radius_m,
        )
        return self.unit.step(dt_s, self.inputs)

    @property
    def status(self) -> VcuStatus:
        return self.unit.status
