"""The vehicle control unit (VCU) of seed 003 §3: torque split, slip protection, blended
braking, failure/limitation management and the range extender's energy management.

The VCU reaches the plant only through :class:`onboard.plant.interfaces.ActuatorCommands`.
Abbreviations: SOC state of charge, BMS battery management system, RE range extender,
I²T the battery's thermal overload integral.
"""

from onboard.vcu.braking import BlendedBraking, BrakingSplit, electric_share
from onboard.vcu.limits import BatteryOverload, EnergyManager, SlipperyRail, temperature_factor
from onboard.vcu.manoeuvres import (
    Manoeuvre,
    ManoeuvreRecord,
    acceleration_manoeuvre,
    braking_manoeuvre,
    friction_drop_manoeuvre,
    run_manoeuvre,
    vcu_parameters_for,
)
from onboard.vcu.mission import SEED003_MISSION_VEHICLE, MissionRecord, run_energy_mission
from onboard.vcu.parameters import BrakingPhase, Limitation, VcuInputs, VcuParameters, VcuStatus
from onboard.vcu.traction import (
    AxleSlipProtection,
    TorqueSplit,
    leading_share,
    motor_torque_limit_nm,
)
from onboard.vcu.unit import SpeedLoop, VehicleControlUnit

__all__ = [
    "SEED003_MISSION_VEHICLE",
    "MissionRecord",
    "run_energy_mission",
    "Manoeuvre",
    "ManoeuvreRecord",
    "acceleration_manoeuvre",
    "braking_manoeuvre",
    "friction_drop_manoeuvre",
    "run_manoeuvre",
    "vcu_parameters_for",
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
    "VcuInputs",
    "VcuParameters",
    "VcuStatus",
    "VehicleControlUnit",
    "electric_share",
    "leading_share",
    "motor_torque_limit_nm",
    "temperature_factor",
]
