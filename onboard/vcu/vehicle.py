"""The bogie-fidelity vehicle: VCU → 10-DOF bogie + powertrain, behind the point mass's face.

The onboard process drives its plant with a longitudinal force demand and reads position, speed
and acceleration; :class:`BogieVehicle` offers the same members as
:class:`~onboard.plant.point_mass.PointMassModel`, so a vehicle's fidelity is a setting. The
demand goes to the VCU, which commands the bogie's motors and brakes; the powertrain follows.
The VCU's fused speed is the true speed here (ideal positioning, until the sensor-fusion
issue), and the wheel speeds are the bogie's.
"""

from __future__ import annotations

import dataclasses
import math

from onboard.plant.bogie import BogieModel
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS, BogieParameters
from onboard.plant.interfaces import BogieTruth
from onboard.plant.powertrain import Powertrain, PowertrainParameters
from onboard.vcu.feedback import step_powertrain, vcu_inputs, vcu_parameters_for
from onboard.vcu.unit import VehicleControlUnit

__all__ = ["BogieVehicle"]

FORWARD = 1


class BogieVehicle:
    """A forward-running vehicle on the bogie model, controlled through its VCU."""

    def __init__(
        self,
        parameters: BogieParameters = URV_BOGIE_PARAMETERS,
        *,
        position_m: float = 0.0,
        initial_soc: float = 0.9,
    ) -> None:
        self.parameters = parameters
        self.plant = BogieModel(parameters, position_m=position_m)
        self.powertrain = Powertrain(PowertrainParameters(), soc=initial_soc)
        self.vcu = VehicleControlUnit(vcu_parameters_for(parameters))
        self._truth: BogieTruth = self.plant.truth()
        self.adhesion_factor = 1.0
        """μ₀ of the wheel–rail contact is scaled by this: below 1 on a wet or leafy patch."""

    @property
    def truth(self) -> BogieTruth:
        return self._truth

    @property
    def position_m(self) -> float:
        return self._truth.position_m

    @property
    def speed_mps(self) -> float:
        return max(self._truth.speed_mps, 0.0)

    @property
    def acceleration_mps2(self) -> float:
        return self._truth.acceleration_mps2

    @property
    def applied_force_n(self) -> float:
        """Motor minus brake torques over the wheel radius [N]: what the actuators apply."""
        t = self._truth
        motors = t.motor_torque_front_nm + t.motor_torque_rear_nm
        brakes = abs(t.brake_torque_front_nm) + abs(t.brake_torque_rear_nm)
        return (motors - brakes) / t.wheel_radius_m

    @property
    def traction_energy_j(self) -> float:
        return self._truth.traction_energy_j

    def force_limits_n(self, speed_mps: float) -> tuple[float, float]:
        """(min, max) force [N] the VCU can deliver at this speed, both axles together."""
        p = self.parameters
        radius = p.wheel_radius_m
        omega = max(speed_mps, 1.0) / radius
        torque = min(p.motor_max_torque_nm, p.motor_max_power_w / omega)
        brake = p.brake_gain_m3 * p.brake_max_pressure_pa
        return -2.0 * brake / radius, 2.0 * torque / radius

    def step(
        self,
        dt_s: float,
        force_demand_n: float,
        *,
        gradient_permille: float = 0.0,
        curve_radius_m: float = math.inf,
        emergency_brake: float = 0.0,
    ) -> None:
        """Advance by ``dt_s`` [s]; curve resistance is not in the planar bogie model.

        ``emergency_brake`` (0 to 1, the EB's share as the brake pipe vents) acts below the
        VCU, as the pipe acts on the brake cylinders: motors off, each pneumatic brake at least
        that share of its maximum pressure.
        """
        del curve_radius_m
        speed = self.speed_mps
        inputs = vcu_inputs(FORWARD, self._truth, speed, force_demand_n, self.powertrain)
        commands = self.vcu.step(dt_s, inputs)
        if emergency_brake > 0.0:
            pipe_pa = min(emergency_brake, 1.0) * self.parameters.brake_max_pressure_pa
            commands = dataclasses.replace(
                commands,
                motor_torque_front_nm=0.0,
                motor_torque_rear_nm=0.0,
                brake_pressure_front_pa=max(commands.brake_pressure_front_pa, pipe_pa),
                brake_pressure_rear_pa=max(commands.brake_pressure_rear_pa, pipe_pa),
            )
        self.plant.step(dt_s, commands, gradient_permille=gradient_permille,
                        adhesion_factor=self.adhesion_factor)  # fmt: skip
        self._truth = self.plant.truth()
        step_powertrain(self.powertrain, dt_s, self._truth, commands.range_extender_power_w)
