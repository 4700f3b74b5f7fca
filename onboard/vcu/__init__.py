"""The vehicle control unit (VCU) of seed 003 §3: torque split, slip protection, blended
braking, failure/limitation management and the range extender's energy management.

The VCU reaches the plant only through :class:`onboard.plant.interfaces.ActuatorCommands`.
Abbreviations: SOC state of charge, BMS battery management system, RE range extender,
I²T the battery's thermal overload integral.

The seed 003 missions and manoeuvres that drive the VCU in closed loop for tests and benches are
in :mod:`deploy.bench.vcu_mission` and :mod:`deploy.bench.vcu_manoeuvres`.
"""

from onboard.vcu.braking import BlendedBraking, BrakingSplit, electric_share
from onboard.vcu.drive import VcuDrive
from onboard.vcu.limits import BatteryOverload, EnergyManager, SlipperyRail, temperature_factor
from onboard.vcu.parameters import (
    BrakingPhase,
    Limitation,
    VcuInputs,
    VcuParameters,
    VcuStatus,
    vcu_parameters_for,
)
from onboard.vcu.traction import (
    AxleSlipProtection,
    TorqueSplit,
    leading_share,
    motor_torque_limit_nm,
)
from onboard.vcu.unit import SpeedLoop, VehicleControlUnit

__all__ = [
    "AxleSlipProtection",
    "BatteryOverload",
    "BlendedBraking",
    "BrakingPhase",
    "BrakingSplit",
    "EnergyManager",
    "Limitation",
    "SlipperyRail",
    "SpeedLoop",
    "TorqueSplit",
    "VcuDrive",
    "VcuDrive",
    "VcuInputs",
    "VcuParameters",
    "VcuStatus",
    "VehicleControlUnit",
    "electric_share",
    "leading_share",
    "motor_torque_limit_nm",
    "temperature_factor",
    "vcu_parameters_for",
]
