"""Seed 003 §7.1–7.2 energy missions on the point-mass fidelity: speed loop → VCU → plant.

The VCU's own speed loop tracks a constant reference; the axle torques and brake pressures it
commands become a force on :class:`~onboard.plant.point_mass.PointMassModel` (sum of motor
torques over the wheel radius minus the brakes'), and the drives' mechanical powers (torque ×
wheel speed) feed :class:`~onboard.plant.powertrain.Powertrain`. The point mass has no slip,
so both wheel speeds are v / r and the fused speed is the true speed.

The vehicle is the URV (``SEED003_MISSION_VEHICLE`` is ``URV_PARAMETERS``): seed 003 §7.2 ends
in P_drives = P_RE = 100 kW while holding 200 km/h, so the URV's resistance was chosen to keep
the cruise load at 200 km/h below the range extender's 100 kW.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from deploy.bench.vcu_closed_loop import powertrain_feedback
from onboard.plant.point_mass import URV_PARAMETERS, PointMassModel, PointMassParameters
from onboard.plant.powertrain import Powertrain, PowertrainParameters, PowertrainState
from onboard.vcu.parameters import VcuInputs, VcuParameters
from onboard.vcu.unit import VehicleControlUnit
from protocol.units import MPS_PER_KMH

__all__ = ["SEED003_MISSION_VEHICLE", "MissionRecord", "run_energy_mission"]

SEED003_MISSION_VEHICLE = URV_PARAMETERS
"""The URV itself: its resistance was chosen so that these missions hold (see point_mass.py)."""

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class MissionRecord:
    """Time series of a mission, one sample per ``record_every_s`` [s], SI units."""

    time_s: FloatArray
    position_m: FloatArray
    speed_mps: FloatArray
    soc: FloatArray
    battery_power_w: FloatArray
    drives_power_w: FloatArray
    range_extender_power_w: FloatArray
    fuel_kg: FloatArray


def run_energy_mission(
    *,
    initial_soc: float,
    distance_m: float = 200_000.0,
    speed_reference_mps: float = 200.0 * MPS_PER_KMH,
    dt_s: float = 0.1,
    record_every_s: float = 10.0,
    vehicle: PointMassParameters = SEED003_MISSION_VEHICLE,
    vcu_parameters: VcuParameters | None = None,
    powertrain_parameters: PowertrainParameters | None = None,
    gradient_permille: Callable[[float], float] | None = None,
) -> MissionRecord:
    """Run at ``speed_reference_mps`` [m/s] from that speed until ``distance_m`` [m] is done.

    ``dt_s`` [s] is the step of every component (0.1 s keeps a 3600 s mission to a second or
    two). ``gradient_permille`` gives the gradient [‰] at a distance [m] (level without it).
    Returns the recorded series; nothing is written anywhere.
    """
    if distance_m <= 0.0 or dt_s <= 0.0:
        raise ValueError("the mission needs a positive distance and time step")
    vcu_p = vcu_parameters if vcu_parameters is not None else VcuParameters()
    plant = PointMassModel(vehicle, speed_mps=speed_reference_mps)
    powertrain = Powertrain(
        powertrain_parameters if powertrain_parameters is not None else PowertrainParameters(),
        soc=initial_soc,
    )
    vcu = VehicleControlUnit(vcu_p)
    rows: list[tuple[float, ...]] = []
    every = max(round(record_every_s / dt_s), 1)
    step = 0
    while plant.position_m < distance_m:
        state = _mission_step(
            vcu, vcu_p, plant, powertrain, dt_s, speed_reference_mps, gradient_permille
        )
        step += 1
        row = (
            step * dt_s,
            plant.position_m,
            plant.speed_mps,
            state.soc,
            state.battery_power_w,
            state.drives_power_w,
            state.range_extender_power_w,
            state.fuel_kg,
        )
        if step % every == 0:
            rows.append(row)
    if step % every != 0:
        rows.append(row)
    columns = np.array(rows, dtype=np.float64).T
    return MissionRecord(*(np.ascontiguousarray(column) for column in columns))


def _mission_step(
    vcu: VehicleControlUnit,
    vcu_p: VcuParameters,
    plant: PointMassModel,
    powertrain: Powertrain,
    dt_s: float,
    speed_reference_mps: float,
    gradient_permille: Callable[[float], float] | None,
) -> PowertrainState:
    """One step of ``dt_s`` [s] of the speed loop, the point mass (on the gradient [‰] at its
    position) and the powertrain; the powertrain's state after it."""
    radius = vcu_p.wheel_radius_m
    omega = plant.speed_mps / radius
    commands = vcu.step(
        dt_s,
        powertrain_feedback(
            powertrain,
            VcuInputs(
                speed_reference_mps=speed_reference_mps,
                fused_speed_mps=plant.speed_mps,
                wheel_speed_front_radps=omega,
                wheel_speed_rear_radps=omega,
            ),
        ),
    )
    motor_torque = commands.motor_torque_front_nm + commands.motor_torque_rear_nm
    pressure = commands.brake_pressure_front_pa + commands.brake_pressure_rear_pa
    brake_torque = vcu_p.brake_gain_nm_per_pa * pressure
    gradient = 0.0 if gradient_permille is None else gradient_permille(plant.position_m)
    plant.step(dt_s, (motor_torque - brake_torque) / radius, gradient_permille=gradient)
    return powertrain.step(
        dt_s,
        mechanical_power_front_w=commands.motor_torque_front_nm * omega,
        mechanical_power_rear_w=commands.motor_torque_rear_nm * omega,
        range_extender_reference_w=commands.range_extender_power_w,
        motor_torque_front_nm=commands.motor_torque_front_nm,
        motor_torque_rear_nm=commands.motor_torque_rear_nm,
    )
