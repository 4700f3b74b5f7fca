"""The plant's public outputs: what the vehicle's sensors give the rest of the onboard process.

This is the truth boundary of ARCHITECTURE.md. The plant (dynamics, actuators) and the sensor
models (:mod:`onboard.plant.sensors`, :mod:`onboard.plant.balise_reader`) read the vehicle's
true state; every other onboard part (ETCS, ATO-OB, ADF, VC, VCU, SFA, track database manager)
sees the train only through the readings below, through messages and through its own estimates.
``tests/test_architecture.py`` keeps it so: outside ``onboard/plant/`` only this module (and the
vehicle data) may be imported from the plant.

Every reading is what a sensor delivers, with its errors already in it: a wheel's travel as the
calibrated wheel diameter converts its rotation (wear, slip and slide included), a balise group
when the antenna's reader reports it (with its own location error), the drives' and the
batteries' feedback as their controllers report it.
"""

from __future__ import annotations

from dataclasses import dataclass

from trackdb import BaliseGroup, StopMarker

__all__ = [
    "BaliseDetection",
    "DriveReading",
    "MarkerDetection",
    "PowertrainReading",
    "WheelReading",
]


@dataclass(frozen=True, slots=True)
class WheelReading:
    """The axle-end sensors at one instant.

    Each axle's rotation since power-up, times the wheel radius the vehicle is calibrated with:
    the distance [m] and speed [m/s] a pulse counter on that axle sees. A worn wheel (a real
    diameter smaller than the calibrated one) reads long; a slipping wheel reads fast, a sliding
    one slow. The travel is continuous: each consumer's pulse counter quantises it.
    """

    time_s: float
    travel_front_m: float
    travel_rear_m: float
    speed_front_mps: float
    speed_rear_mps: float


@dataclass(frozen=True, slots=True)
class BaliseDetection:
    """A balise group read by the BTM: its telegram (the group's packets and identity), and the
    instant [s] the reader located the group's centre under the antenna (with the reader's
    location error: the front end was then near, not exactly at, the group)."""

    time_s: float
    group: BaliseGroup


@dataclass(frozen=True, slots=True)
class MarkerDetection:
    """A precision-stop marker found by the marker reader: the marker, and the instant [s] the
    reader located its centre under the cab (within a few centimetres of it)."""

    time_s: float
    marker: StopMarker


@dataclass(frozen=True, slots=True)
class DriveReading:
    """The drives' and brakes' feedback: the longitudinal force they apply at the rail [N]
    (motor torque feedback minus brake cylinder pressures, as the traction control computes it)."""

    time_s: float
    applied_force_n: float


@dataclass(frozen=True, slots=True)
class PowertrainReading:
    """What the battery management systems, the range extender's controller and the drives'
    temperature sensors report to the VCU (seed 003 fig. 10's buses), SI units."""

    time_s: float
    soc: float
    battery_voltage_v: float
    battery_current_a: float
    """Positive discharging [A]."""
    max_discharge_power_w: float
    max_charge_power_w: float
    continuous_current_a: float
    range_extender_power_w: float
    motor_temperature_front_c: float
    motor_temperature_rear_c: float
