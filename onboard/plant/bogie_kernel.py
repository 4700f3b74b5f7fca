"""The bogie model's substeps, compiled: what :class:`~onboard.plant.bogie.BogieModel` runs
for each 10 ms step, as numba functions on the model's arrays.

The model's physics and integrator are those written in :mod:`onboard.plant.bogie`; this
module is their arithmetic on flat float arrays, in one call a step, so that the interpreter
does not take ~35 µs a substep on some sixty float operations and a dozen small numpy calls
(docs/perf.md, "The bogie compiled"). The Polach creep force and the saturated sign are
:mod:`onboard.plant.contact`'s own functions, compiled here: one formula.

Compiled on first use and cached on disk (:mod:`onboard.runtime.compiled`); with
``NUMBA_DISABLE_JIT=1`` the same functions run in the interpreter, for debugging.

The arrays (all float64; indices below):

- ``q``, ``v``: the generalised coordinates and velocities (10);
- ``actuators``: the motors' lagged torque references and the cylinders' pressures;
- ``terms``: per wheelset (rows), what the last evaluation found (columns ``CREEP`` ...);
- ``loads``: Q less drag and gravity as evaluated, then drag and lift, then q̇ as evaluated;
- ``energy``: the bookkeeping's sums (``TRACTION`` ...);
- ``matrices``: [M], [C], [K], [M]⁻¹; ``system``: M + hC + h²K and C + hK for the substep h;
- ``vectors``: the carbody's longitudinal row, gravity along and across the track;
- ``constants``: the parameters the forces read (``_STATIC_LOAD`` ...).
"""

from __future__ import annotations

import math

import numpy as np

from onboard.plant import bogie_parameters, contact
from onboard.plant.bogie_parameters import DOF
from onboard.runtime.compiled import compiled
from protocol import units
from protocol.units import GRAVITY_MPS2

__all__ = [
    "CONSTANTS",
    "ENERGY_ENTRIES",
    "TERMS",
    "Gravity",
    "Model",
    "State",
    "advance",
    "evaluate",
]

_jit = compiled(contact, bogie_parameters, units)
"""These functions inline contact's formula and read constants of two more modules."""
_polach = _jit(contact.polach_force)
_sign = _jit(contact.saturated_sign)

_PITCH = 2
_X = (4, 7)
_Z = (5, 8)
_SPIN = (6, 9)
"""Indices of the bogie's pitch and of each wheelset's x, z and spin in q."""

# terms' columns
CREEP, CREEP_SLOPE, SLIP, BRAKE, BRAKE_SLOPE, ROLLING, ROLLING_SLOPE, MOTOR, NORMAL = range(9)
TERMS = 9
# loads' rows
_FORCES, _AERO, _EVALUATED_V = range(3)
_DRAG, _LIFT = 0, 1
# energy's entries
TRACTION, REGEN, DAMPING_LOSS, CREEP_LOSS, ROLLING_LOSS, BRAKE_LOSS, AERO_LOSS, GRAVITY_WORK = (
    range(8)
)
ENERGY_ENTRIES = 8
# matrices' and vectors' rows
_MASS, _DAMPING_M, _STIFFNESS, _MASS_INVERSE = range(4)
_BASE, _DAMPING_H = range(2)
_LONGITUDINAL, _ALONG, _NORMAL_G = range(3)
# constants' entries
(
    _STATIC_LOAD,
    _CONTACT_STIFFNESS,
    _CONTACT_DAMPING,
    _RADIUS,
    _BETA,
    _BRAKE_GAIN,
    _ROLLING_COEFFICIENT,
    _MAX_TORQUE,
    _MAX_POWER,
    _STATIC_FRICTION,
    _FRICTION_RATIO,
    _DECAY_RATE,
    _CREEP_COEFFICIENT,
    _REDUCTION_ADHESION,
    _REDUCTION_SLIP,
    _AIR_DENSITY,
    _DRAG_AREA,
    _LIFT_AREA,
    _MOTOR_TIME_CONSTANT,
    _BRAKE_TIME_CONSTANT,
    _BRAKE_MAX_PRESSURE,
) = range(21)
CONSTANTS = 21

State = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""(q, v, actuators, terms, loads, energy): what a step changes."""
Model = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""(matrices, system, vectors, constants): what a step reads."""
Gravity = tuple[float, float]
"""The sine and cosine of the gradient's angle."""


@_jit
def _dot(row: np.ndarray, x: np.ndarray) -> float:
    total = 0.0
    for index in range(x.shape[0]):
        total += row[index] * x[index]
    return total


@_jit
def _wheelset(
    axle: int,
    q: np.ndarray,
    v: np.ndarray,
    actuators: np.ndarray,
    terms: np.ndarray,
    forces: np.ndarray,
    c: np.ndarray,
    static_friction: float,
) -> None:
    """One wheelset's creep force, brake, rolling and motor torques into ``forces``, and its
    terms and stiff slopes into its row of ``terms``. The motor's torque is its lagged
    reference limited by the torque–speed curve (max torque, then max power)."""
    radius, beta = c[_RADIUS], c[_BETA]
    ix, iz, ispin = _X[axle], _Z[axle], _SPIN[axle]
    normal = c[_STATIC_LOAD] - c[_CONTACT_STIFFNESS] * q[iz] - c[_CONTACT_DAMPING] * v[iz]
    spin = v[ispin]
    slip = v[ix] - radius * spin
    creep, creep_slope = _polach(
        slip,
        v[ix],
        normal,
        static_friction,
        c[_FRICTION_RATIO],
        c[_DECAY_RATE],
        c[_CREEP_COEFFICIENT],
        c[_REDUCTION_ADHESION],
        c[_REDUCTION_SLIP],
    )
    relative_spin = spin + v[_PITCH]
    brake_gain = c[_BRAKE_GAIN] * actuators[2 + axle]
    brake = -brake_gain * _sign(relative_spin, beta)
    rolling_gain = max(normal, 0.0) * radius * c[_ROLLING_COEFFICIENT]
    rolling = -rolling_gain * _sign(spin, beta)
    limit = c[_MAX_TORQUE]
    speed = abs(spin)
    if speed * limit > c[_MAX_POWER]:
        limit = c[_MAX_POWER] / speed
    motor = min(max(actuators[axle], -limit), limit)
    forces[ix] += creep
    forces[ispin] += motor + brake + rolling - radius * creep
    forces[_PITCH] += motor + brake
    t = terms[axle]
    t[CREEP], t[CREEP_SLOPE], t[SLIP] = creep, creep_slope, slip
    t[BRAKE] = brake
    t[BRAKE_SLOPE] = -brake_gain / beta if abs(relative_spin) < beta else 0.0
    t[ROLLING] = rolling
    t[ROLLING_SLOPE] = -rolling_gain / beta if speed < beta else 0.0
    t[MOTOR], t[NORMAL] = motor, normal


@_jit
def evaluate(state: State, model: Model, gravity: Gravity, adhesion_factor: float) -> None:
    """Q less drag and gravity, each wheelset's terms and stiff slopes, at the current state."""
    q, v, actuators, terms, loads, _ = state
    _, _, vectors, c = model
    sin_a, cos_a = gravity
    static_friction = c[_STATIC_FRICTION] * adhesion_factor
    forces = loads[_FORCES]
    forces[:] = 0.0
    for axle in range(2):
        _wheelset(axle, q, v, actuators, terms, forces, c, static_friction)
    air_speed = _dot(vectors[_LONGITUDINAL], v)
    dynamic = 0.5 * c[_AIR_DENSITY] * air_speed * abs(air_speed)
    drag = dynamic * c[_DRAG_AREA]
    lift = abs(dynamic) * c[_LIFT_AREA]
    loads[_AERO, _DRAG], loads[_AERO, _LIFT] = drag, lift
    forces[1] += lift
    along = GRAVITY_MPS2 * sin_a
    across = GRAVITY_MPS2 * (cos_a - 1.0)
    for index in range(DOF):
        forces[index] = (
            forces[index]
            - drag * vectors[_LONGITUDINAL, index]
            - along * vectors[_ALONG, index]
            + across * vectors[_NORMAL_G, index]
        )
    loads[_EVALUATED_V, :] = v


@_jit
def _lag_actuators(
    actuators: np.ndarray, constants: np.ndarray, h: float, torques: np.ndarray
) -> None:
    """Exact discretisation of the first-order lags: the same response at any substep."""
    motor_blend = -math.expm1(-h / constants[_MOTOR_TIME_CONSTANT])
    brake_blend = -math.expm1(-h / constants[_BRAKE_TIME_CONSTANT])
    for axle in range(2):
        actuators[axle] += (torques[axle] - actuators[axle]) * motor_blend
        reference = min(max(torques[2 + axle], 0.0), constants[_BRAKE_MAX_PRESSURE])
        actuators[2 + axle] += (reference - actuators[2 + axle]) * brake_blend


@_jit
def _account(
    h: float, velocity: np.ndarray, weight: float, state: State, model: Model, gravity: Gravity
) -> None:
    """Add this substep's work of every force, evaluated with the substep's velocities
    (``weight`` 1: the linearised forces of the implicit scheme; 0: the explicit's)."""
    _, _, _, terms, loads, energy = state
    matrices, _, vectors, constants = model
    sin_a, cos_a = gravity
    radius = constants[_RADIUS]
    old = loads[_EVALUATED_V]
    for axle in range(2):
        ix, ispin = _X[axle], _SPIN[axle]
        t = terms[axle]
        relative_spin = velocity[ispin] + velocity[_PITCH]
        work = t[MOTOR] * relative_spin * h
        if work >= 0.0:
            energy[TRACTION] += work
        else:
            energy[REGEN] -= work
        slip = velocity[ix] - radius * velocity[ispin]
        creep = t[CREEP] + weight * t[CREEP_SLOPE] * (slip - t[SLIP])
        energy[CREEP_LOSS] -= creep * slip * h
        old_relative = old[ispin] + old[_PITCH]
        brake_change = t[BRAKE_SLOPE] * (relative_spin - old_relative)
        energy[BRAKE_LOSS] -= (t[BRAKE] + weight * brake_change) * relative_spin * h
        rolling_change = t[ROLLING_SLOPE] * (velocity[ispin] - old[ispin])
        energy[ROLLING_LOSS] -= (t[ROLLING] + weight * rolling_change) * velocity[ispin] * h
    air_speed = _dot(vectors[_LONGITUDINAL], velocity)
    energy[AERO_LOSS] += (loads[_AERO, _DRAG] * air_speed - loads[_AERO, _LIFT] * velocity[1]) * h
    damping = 0.0
    gravity_work = 0.0
    along = GRAVITY_MPS2 * sin_a
    across = GRAVITY_MPS2 * (cos_a - 1.0)
    for row in range(DOF):
        damping += velocity[row] * _dot(matrices[_DAMPING_M, row], velocity)
        force = -along * vectors[_ALONG, row] + across * vectors[_NORMAL_G, row]
        gravity_work += force * velocity[row]
    energy[DAMPING_LOSS] += damping * h
    energy[GRAVITY_WORK] += gravity_work * h


@_jit
def _implicit(h: float, state: State, model: Model, gravity: Gravity) -> None:
    """One linearly implicit Euler substep: the stiff slopes enter 13 entries of the system."""
    q, v, _, terms, loads, _ = state
    matrices, system, _, constants = model
    radius = constants[_RADIUS]
    a = system[_BASE].copy()
    for axle in range(2):
        ix, ispin = _X[axle], _SPIN[axle]
        t = terms[axle]
        creep = h * t[CREEP_SLOPE]
        brake = h * t[BRAKE_SLOPE]
        a[ix, ix] -= creep
        a[ix, ispin] += radius * creep
        a[ispin, ix] += radius * creep
        a[ispin, ispin] -= radius * radius * creep + brake + h * t[ROLLING_SLOPE]
        a[ispin, _PITCH] -= brake
        a[_PITCH, ispin] -= brake
        a[_PITCH, _PITCH] -= brake
    rhs = np.empty(DOF)
    forces = loads[_FORCES]
    for row in range(DOF):
        rhs[row] = h * (
            forces[row] - _dot(system[_DAMPING_H, row], v) - _dot(matrices[_STIFFNESS, row], q)
        )
    velocity = v + np.linalg.solve(a, rhs)
    _account(h, velocity, 1.0, state, model, gravity)
    v[:] = velocity
    for row in range(DOF):
        q[row] += h * velocity[row]


@_jit
def _explicit(h: float, state: State, model: Model, gravity: Gravity) -> None:
    """One forward Euler substep (the seed's scheme)."""
    q, v, _, _, loads, _ = state
    matrices = model[0]
    forces = loads[_FORCES]
    net = np.empty(DOF)
    for row in range(DOF):
        net[row] = (
            forces[row] - _dot(matrices[_DAMPING_M, row], v) - _dot(matrices[_STIFFNESS, row], q)
        )
    velocity = np.empty(DOF)
    for row in range(DOF):
        velocity[row] = v[row] + h * _dot(matrices[_MASS_INVERSE, row], net)
    _account(h, v, 0.0, state, model, gravity)
    for row in range(DOF):
        q[row] += h * v[row]
    v[:] = velocity


@_jit
def advance(
    count: int,
    h: float,
    references: np.ndarray,
    gravity: Gravity,
    adhesion_factor: float,
    implicit: bool,
    state: State,
    model: Model,
) -> None:
    """``count`` substeps of ``h`` under the references (motor torques front and rear, then
    brake pressures), then the forces evaluated at the end state."""
    actuators, constants = state[2], model[3]
    for _ in range(count):
        _lag_actuators(actuators, constants, h, references)
        evaluate(state, model, gravity, adhesion_factor)
        if implicit:
            _implicit(h, state, model, gravity)
        else:
            _explicit(h, state, model, gravity)
    evaluate(state, model, gravity, adhesion_factor)
