"""What crosses the boundary between the VCU (control) and the plant (truth), seed 003.

The VCU reaches the plant only through :class:`ActuatorCommands` (the TIU/VCU outputs: motor
torque and brake pressure references per axle, the range extender's power reference). The plant
exposes its truth as :class:`BogieTruth`, which sensors and KPIs read; controllers see the train
only through sensors.

Axles are named by the vehicle, not by the direction of motion: ``front`` is the leading axle
when running forwards. The VCU works out which one trails.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ActuatorCommands", "BogieTruth"]


@dataclass(frozen=True, slots=True)
class ActuatorCommands:
    """References to the actuators, as the VCU sends them.

    Motor torques are at the wheelset (after the gearbox) [N·m], positive driving the vehicle
    forwards, negative braking electrically. Brake pressures [Pa] are the pneumatic brake
    cylinder references, at least 0. The range extender power reference [W] is at least 0.
    """

    motor_torque_front_nm: float = 0.0
    motor_torque_rear_nm: float = 0.0
    brake_pressure_front_pa: float = 0.0
    brake_pressure_rear_pa: float = 0.0
    range_extender_power_w: float = 0.0


@dataclass(frozen=True, slots=True)
class BogieTruth:
    """The bogie model's state and what it did, SI units."""

    time_s: float
    position_m: float
    speed_mps: float
    acceleration_mps2: float
    wheel_speed_front_radps: float
    wheel_speed_rear_radps: float
    wheel_radius_m: float
    motor_torque_front_nm: float
    motor_torque_rear_nm: float
    brake_torque_front_nm: float
    brake_torque_rear_nm: float
    normal_force_front_n: float
    normal_force_rear_n: float
    creepage_front: float
    creepage_rear: float
    traction_energy_j: float
    """Mechanical energy delivered by the motors at the wheels while driving."""
    regen_energy_j: float
    """Mechanical energy taken by the motors at the wheels while braking electrically."""
