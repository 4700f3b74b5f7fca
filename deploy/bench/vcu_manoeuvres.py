"""Short closed-loop manoeuvres on the bogie model: VCU → 10-DOF bogie + powertrain → VCU.

Seed 003 §7.3–7.4 show the VCU's torque split, blended braking and slip protection, which the
point mass of :mod:`deploy.bench.vcu_mission` cannot show (it has no wheels). Here the VCU commands
:class:`~onboard.plant.bogie.BogieModel` and :class:`~onboard.plant.powertrain.Powertrain`
every ``dt_s`` and reads back, as over its CAN buses:

- the axles' measured rotational speeds, from :class:`~onboard.plant.interfaces.BogieTruth`
  (the seed's "measured speed" is that times the rolling radius);
- a fused vehicle speed: the true speed plus white Gaussian noise of ``fused_speed_noise_mps``
  [m/s] standard deviation from a generator seeded with ``seed``, floored at 0. It stands for
  the positioning unit's GPS/IMU-fused speed (seed 003 §3.1), which does not see wheel slip;
  0.05 m/s is about what a Doppler GPS fused with an IMU gives;
- the BMS limits, range-extender output and drive temperatures from the powertrain.

The drives' powers come from the plant's actual motor torques (after their lag and torque–speed
curve) times the axles' speeds. The VCU's parameters are derived from the bogie's
(:func:`~onboard.vcu.parameters.vcu_parameters_for`) so that the torques and pressures it
commands mean to the plant what the VCU means by them. A bench of the VCU alone
(``ato bench plant --plots``, the seed 003 tests); the onboard process runs the same loop in
:class:`onboard.vcu.vehicle.BogieVehicle`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from deploy.bench.vcu_closed_loop import step_powertrain, vcu_inputs
from onboard.plant.bogie import BogieModel
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS, BogieParameters
from onboard.plant.interfaces import ActuatorCommands, BogieTruth
from onboard.plant.powertrain import Powertrain, PowertrainParameters
from onboard.vcu import vcu_parameters_for
from onboard.vcu.parameters import VcuParameters
from onboard.vcu.unit import VehicleControlUnit
from protocol.units import MPS_PER_KMH

__all__ = [
    "ACCELERATION_FORCE_N",
    "BRAKING_FORCE_N",
    "FRICTION_DROP_ADHESION",
    "FRICTION_DROP_FORCE_N",
    "FRICTION_DROP_PATCH_M",
    "MANOEUVRE_STEP_S",
    "Manoeuvre",
    "ManoeuvreRecord",
    "acceleration_manoeuvre",
    "braking_manoeuvre",
    "friction_drop_manoeuvre",
    "run_manoeuvre",
]

MANOEUVRE_STEP_S = 0.01
"""Step [s] of the VCU and of the plant's ``step`` calls: a 10 ms CAN cycle."""

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
StrArray = npt.NDArray[np.str_]
_Row = tuple[float | bool | str, ...]


ACCELERATION_FORCE_N = 20_000.0
"""Seed 003 §7.3 acceleration: demand [N] ramped at 10 kN/s; above one axle's 15 kN."""
BRAKING_FORCE_N = 15_000.0
"""Seed 003 §7.3 braking: demand [N] ramped in 1 s from 60 km/h to a stop (about 1 m/s²)."""
FRICTION_DROP_FORCE_N = 16_000.0
"""Seed 003 §7.4: traction demand [N], below the slippery-rail limit of 60 % × 30 kN."""
FRICTION_DROP_ADHESION = 0.2
"""Scale on μ₀ on the low-adhesion patch: μ₀ = 0.55 becomes 0.11."""
FRICTION_DROP_PATCH_M = (20.0, 70.0)
"""Where the patch starts and ends [m], as distance travelled from the start."""


def _dry_rail(_distance_m: float) -> float:
    return 1.0


def _ramp(level_n: float, rate_n_per_s: float) -> Callable[[float, float], float]:
    def demand(time_s: float, _speed_mps: float) -> float:
        return math.copysign(min(abs(level_n), rate_n_per_s * time_s), level_n)

    return demand


def _friction_drop(distance_m: float) -> float:
    start, end = FRICTION_DROP_PATCH_M
    return FRICTION_DROP_ADHESION if start <= distance_m < end else 1.0


@dataclass(frozen=True, kw_only=True)
class Manoeuvre:
    """A short manoeuvre: demand, starting state, rail condition and noise.

    Parameters
    ----------
    duration_s : float
        Simulated time [s].
    force_demand_n : Callable[[float, float], float]
        Force demand at the rail [N] as a function of (time [s], fused speed [m/s]); positive
        pulls in the direction of motion, negative brakes.
    initial_speed_mps : float
        Starting speed along the direction of motion [m/s], at least 0.
    direction : int
        +1 forwards, −1 in reverse.
    adhesion_factor : Callable[[float], float]
        Scale on μ₀ as a function of the distance travelled [m]; 1 on dry rail.
    initial_soc : float
        Both packs' state of charge at the start [fraction].
    fused_speed_noise_mps : float
        Standard deviation [m/s] of the noise on the fused speed.
    seed : int
        Seed of the fused speed's noise.
    stop_below_mps : float or None
        End early once the true speed falls below this [m/s] after the first second.
    """

    duration_s: float
    force_demand_n: Callable[[float, float], float]
    initial_speed_mps: float = 0.0
    direction: int = 1
    adhesion_factor: Callable[[float], float] = _dry_rail
    initial_soc: float = 0.8
    fused_speed_noise_mps: float = 0.05
    seed: int = 3
    stop_below_mps: float | None = None


@dataclass(frozen=True, slots=True)
class ManoeuvreRecord:
    """One sample per step, shape (n,), SI units.

    Speeds are along the direction of motion. Wheel speeds are the axles' peripheral speeds
    ω R [m/s] (the seed's "measured speed"). Motor and brake torques are the plant's actual
    torques at the wheelsets [N·m], signed as in :class:`ActuatorCommands` (vehicle axes) for
    the motors; ``electric_braking_torque_nm`` and ``pneumatic_braking_torque_nm`` are the
    vehicle's totals as positive magnitudes, and ``braking_demand_nm`` the demand's magnitude
    (−force × R when braking, else 0). Powers [W]: battery positive discharging.
    """

    time_s: FloatArray
    distance_m: FloatArray
    speed_mps: FloatArray
    fused_speed_mps: FloatArray
    wheel_speed_front_mps: FloatArray
    wheel_speed_rear_mps: FloatArray
    force_demand_n: FloatArray
    motor_torque_front_nm: FloatArray
    motor_torque_rear_nm: FloatArray
    electric_braking_torque_nm: FloatArray
    pneumatic_braking_torque_nm: FloatArray
    braking_demand_nm: FloatArray
    braking_phase: StrArray
    slip_front: BoolArray
    slip_rear: BoolArray
    adhesion_factor: FloatArray
    soc: FloatArray
    battery_power_w: FloatArray
    drives_power_w: FloatArray
    range_extender_power_w: FloatArray


def acceleration_manoeuvre(direction: int = 1) -> Manoeuvre:
    """Seed 003 §7.3 (fig. 14a,b): 14 s from standstill under a ramped 20 kN demand, to about
    57 km/h, forwards (``direction`` 1) or in reverse (−1)."""
    return Manoeuvre(
        duration_s=14.0, force_demand_n=_ramp(ACCELERATION_FORCE_N, 10_000.0), direction=direction
    )


def braking_manoeuvre() -> Manoeuvre:
    """Seed 003 §7.3 (fig. 14c,d): from 60 km/h to a stop under a 15 kN braking demand."""
    return Manoeuvre(
        duration_s=25.0,
        initial_speed_mps=60.0 * MPS_PER_KMH,
        force_demand_n=_ramp(-BRAKING_FORCE_N, BRAKING_FORCE_N),
        stop_below_mps=0.05,
    )


def friction_drop_manoeuvre(*, adhesion: bool = True) -> Manoeuvre:
    """Seed 003 §7.4 (fig. 15): 13 s of 16 kN traction from 18 km/h over a 50 m patch where
    μ₀ falls to a fifth; ``adhesion=False`` runs the same on dry rail, as the reference."""
    return Manoeuvre(
        duration_s=13.0,
        initial_speed_mps=5.0,
        force_demand_n=_ramp(FRICTION_DROP_FORCE_N, 1.0e9),
        adhesion_factor=_friction_drop if adhesion else _dry_rail,
    )


def run_manoeuvre(
    manoeuvre: Manoeuvre,
    *,
    bogie_parameters: BogieParameters = URV_BOGIE_PARAMETERS,
    vcu_parameters: VcuParameters | None = None,
    powertrain_parameters: PowertrainParameters | None = None,
    dt_s: float = MANOEUVRE_STEP_S,
) -> ManoeuvreRecord:
    """Run ``manoeuvre`` in closed loop on level track and return its time series.

    ``vcu_parameters`` defaults to :func:`~onboard.vcu.parameters.vcu_parameters_for` the
    bogie. The bogie model runs about 25× faster than real time, so a 20 s manoeuvre takes
    under a second.
    """
    if manoeuvre.direction not in (1, -1) or manoeuvre.duration_s <= 0.0 or dt_s <= 0.0:
        raise ValueError("a manoeuvre needs direction ±1 and a positive duration and step")
    sign = float(manoeuvre.direction)
    vcu_p = vcu_parameters if vcu_parameters is not None else vcu_parameters_for(bogie_parameters)
    radius = bogie_parameters.wheel_radius_m
    plant = BogieModel(bogie_parameters, speed_mps=sign * manoeuvre.initial_speed_mps)
    powertrain = Powertrain(
        powertrain_parameters if powertrain_parameters is not None else PowertrainParameters(),
        soc=manoeuvre.initial_soc,
    )
    vcu = VehicleControlUnit(vcu_p)
    rng = np.random.default_rng(manoeuvre.seed)
    truth = plant.truth()
    commands = ActuatorCommands()
    rows: list[_Row] = []
    for _ in range(round(manoeuvre.duration_s / dt_s)):
        speed = sign * truth.speed_mps
        noise = manoeuvre.fused_speed_noise_mps * float(rng.standard_normal())
        fused = max(speed + noise, 0.0)
        distance = sign * truth.position_m
        adhesion = manoeuvre.adhesion_factor(distance)
        force = manoeuvre.force_demand_n(truth.time_s, fused)
        commands = vcu.step(dt_s, vcu_inputs(manoeuvre.direction, truth, fused, force, powertrain))
        plant.step(dt_s, commands, adhesion_factor=adhesion)
        truth = plant.truth()
        step_powertrain(powertrain, dt_s, truth, commands.range_extender_power_w)
        rows.append(_row(sign, radius, truth, fused, force, adhesion, vcu, powertrain))
        stop = manoeuvre.stop_below_mps
        if stop is not None and truth.time_s > 1.0 and sign * truth.speed_mps < stop:
            break
    return _record(rows)


def _row(
    sign: float,
    radius_m: float,
    truth: BogieTruth,
    fused_mps: float,
    force_n: float,
    adhesion: float,
    vcu: VehicleControlUnit,
    powertrain: Powertrain,
) -> _Row:
    """One step's sample, in the order of :class:`ManoeuvreRecord`'s fields."""
    motors = truth.motor_torque_front_nm + truth.motor_torque_rear_nm
    status, state = vcu.status, powertrain.state
    return (
        truth.time_s,
        sign * truth.position_m,
        sign * truth.speed_mps,
        fused_mps,
        sign * truth.wheel_speed_front_radps * radius_m,
        sign * truth.wheel_speed_rear_radps * radius_m,
        force_n,
        truth.motor_torque_front_nm,
        truth.motor_torque_rear_nm,
        max(-sign * motors, 0.0),
        abs(truth.brake_torque_front_nm) + abs(truth.brake_torque_rear_nm),
        max(-force_n * radius_m, 0.0),
        status.braking_phase.value,
        status.slip_front,
        status.slip_rear,
        adhesion,
        state.soc,
        state.battery_power_w,
        state.drives_power_w,
        state.range_extender_power_w,
    )


def _record(rows: list[_Row]) -> ManoeuvreRecord:
    columns = list(zip(*rows, strict=True))
    fields = dataclasses.fields(ManoeuvreRecord)
    arrays: dict[str, npt.NDArray[np.generic]] = {}
    for field, column in zip(fields, columns, strict=True):
        if field.name == "braking_phase":
            arrays[field.name] = np.array(column, dtype=np.str_)
        elif field.name.startswith("slip_"):
            arrays[field.name] = np.array(column, dtype=np.bool_)
        else:
            arrays[field.name] = np.array(column, dtype=np.float64)
    return ManoeuvreRecord(**arrays)  # type: ignore[arg-type]
