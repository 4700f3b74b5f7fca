"""The planar 10-DOF bogie model of seed 003 §5: the vehicle's longitudinal truth with contact.

    [M] q̈ + [C] q̇ + [K] q = Q(q, q̇, t)

with the matrices of :mod:`onboard.plant.bogie_parameters`, and in Q: Polach creep forces
(:mod:`onboard.plant.contact`), rolling-resistance and brake torques with a saturated sign,
drag and lift, gravity along and across the track, and the motors' torques with their reaction
on the bogie. Motors follow their torque reference through a first-order lag and are limited by
their torque–speed curve (max torque, then max power); brake cylinders follow their pressure
reference through a first-order lag, and the brake torque T = −k_p p sign(ω) acts between the
axle and the bogie. The track is locally straight at the given gradient, both contact points on
the incline; the vertical curves between gradients (radii of kilometres) are not modelled.

Integration. The seed integrates with forward Euler at 1e-4 s. The wheel–rail normal contact
(~180 Hz) and above all the creep force at low speed (a time constant of microseconds as the
creepage's denominator approaches 0.1 m/s) make any explicit scheme crawl. We use the linearly
implicit Euler method: per substep h,

    (M + h C + h² K − h ∂Q/∂q̇) Δq̇ = h (Q − C q̇ − K (q + h q̇)),   q ← q + h (q̇ + Δq̇),

with the stiff part of ∂Q/∂q̇ (creep force, brake and rolling torques, per wheelset) evaluated
each substep. It is implicit Euler on the linear part (so L-stable) and first-order accurate.
``integrator="forward_euler"`` gives the seed's scheme, used as the reference in the tests.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from onboard.plant.bogie_parameters import (
    DOF,
    URV_BOGIE_PARAMETERS,
    BogieMatrices,
    BogieParameters,
    Matrix,
    assemble_matrices,
)
from onboard.plant.contact import CreepForce, creep_force_function, creepage, saturated_sign
from onboard.plant.interfaces import ActuatorCommands, BogieTruth
from protocol.units import GRAVITY_MPS2

__all__ = ["DEFAULT_SUBSTEP_S", "BogieEnergy", "BogieModel", "Integrator"]

try:  # numpy's own gufunc behind numpy.linalg.solve (see _solve)
    from numpy.linalg import _umath_linalg

    _SOLVE1: Callable[..., Matrix] | None = _umath_linalg.solve1
except (ImportError, AttributeError):  # a numpy that moved it: the public function
    _SOLVE1 = None

DEFAULT_SUBSTEP_S = 0.002
"""Largest substep [s] of the linearly implicit scheme; ``step`` splits longer steps evenly."""
Integrator = Literal["linearly_implicit", "forward_euler"]

_BOGIE_PITCH = 2
_WHEELSETS = ((4, 5, 6), (7, 8, 9))
"""Indices (x, z, spin) of the front and rear wheelsets in q."""
_STIFF_ENTRIES = np.array(
    [
        *(
            entry
            for ix, _, ispin in _WHEELSETS
            for entry in (
                ix * DOF + ix,
                ix * DOF + ispin,
                ispin * DOF + ix,
                ispin * DOF + ispin,
                ispin * DOF + _BOGIE_PITCH,
                _BOGIE_PITCH * DOF + ispin,
            )
        ),
        _BOGIE_PITCH * DOF + _BOGIE_PITCH,
    ]
)
"""Flat indices of the implicit system's entries that the stiff slopes change (see
``BogieModel._implicit``), in the order it lists their values."""
_PITCH_ENTRY = _BOGIE_PITCH * DOF + _BOGIE_PITCH


@dataclass(frozen=True)
class BogieEnergy:
    """Energy bookkeeping since the model was created [J].

    ``motor_work_j`` (traction minus regeneration at the wheels) equals the change of
    ``kinetic_j`` + ``elastic_j``, less ``gravity_work_j``, plus all the dissipated terms, up to
    the integrator's error (:meth:`residual_j`).
    """

    motor_work_j: float
    kinetic_j: float
    elastic_j: float
    gravity_work_j: float
    damping_j: float
    creep_j: float
    rolling_j: float
    brake_j: float
    aerodynamic_j: float
    initial_mechanical_j: float

    @property
    def dissipated_j(self) -> float:
        return self.damping_j + self.creep_j + self.rolling_j + self.brake_j + self.aerodynamic_j

    def residual_j(self) -> float:
        """Motor work not accounted for by stored energy, gravity and losses [J]."""
        stored = self.kinetic_j + self.elastic_j - self.initial_mechanical_j
        return self.motor_work_j - stored + self.gravity_work_j - self.dissipated_j


def _solve(system: Matrix, rhs: Matrix) -> Matrix:
    """``numpy.linalg.solve(system, rhs)`` for a float64 square system and vector, the same
    bits: the same LAPACK routine through numpy's gufunc, called without the public function's
    checks and error-state context, which took over half of its time (docs/perf.md, "The
    bogie"). A singular system makes the gufunc's result non-finite: it is then solved again
    through the public function, which raises numpy's ``LinAlgError``."""
    if _SOLVE1 is not None:
        solution: Matrix = _SOLVE1(system, rhs, signature="dd->d")
        if math.isfinite(float(solution @ solution)):
            return solution
    return np.linalg.solve(system, rhs).astype(np.float64, copy=False)


class _Gravity:
    """Gravity's generalised forces on one gradient, worked out once a step instead of at each
    substep: along the track, across it (the share of the load the incline takes off), and
    their sum as the energy bookkeeping takes it. The same products as before, so the same
    bits."""

    __slots__ = ("along", "force", "normal")

    def __init__(self, matrices: BogieMatrices, sin_a: float, cos_a: float) -> None:
        along = (GRAVITY_MPS2 * sin_a) * matrices.gravity_along_track
        normal = (GRAVITY_MPS2 * (cos_a - 1.0)) * matrices.gravity_normal
        self.along: list[float] = along.tolist()
        self.normal: list[float] = normal.tolist()
        self.force = -(GRAVITY_MPS2 * sin_a) * matrices.gravity_along_track + normal


class _Linearised:
    """Per-substep generalised forces, their stiff slopes and what the bookkeeping needs."""

    __slots__ = (
        "brake",
        "brake_slope",
        "creep",
        "creep_slope",
        "drag",
        "forces",
        "lift",
        "motor",
        "normal",
        "rolling",
        "rolling_slope",
        "slip",
        "velocities",
    )

    def __init__(self) -> None:
        self.forces = np.zeros(DOF)
        self.creep = [0.0, 0.0]
        self.creep_slope = [0.0, 0.0]
        self.slip = [0.0, 0.0]
        self.brake = [0.0, 0.0]
        self.brake_slope = [0.0, 0.0]
        self.rolling = [0.0, 0.0]
        self.rolling_slope = [0.0, 0.0]
        self.motor = [0.0, 0.0]
        self.normal = [0.0, 0.0]
        self.drag = 0.0
        self.lift = 0.0
        self.velocities: list[float] = [0.0] * DOF
        """q̇ as the evaluation read it (the substep's velocities before the step)."""


class _WheelsetForces:
    """Each wheelset's creep force, brake, rolling and motor torques and their stiff slopes.

    The hot path of the bogie (two wheelsets, six times a 10 ms step): the parameters are read
    once. The motor's torque is its lagged reference limited by the torque–speed curve (max
    torque, then max power).
    """

    __slots__ = ("_constants",)

    def __init__(self, parameters: BogieParameters) -> None:
        p = parameters
        self._constants = (
            p.static_axle_load_n,
            p.contact_stiffness_n_per_m,
            p.contact_damping_ns_per_m,
            p.wheel_radius_m,
            p.sign_saturation_radps,
            p.brake_gain_m3,
            p.rolling_resistance_coefficient,
            p.motor_max_torque_nm,
            p.motor_max_power_w,
        )

    def forces(
        self,
        s: _Linearised,
        q: list[float],
        v: list[float],
        pressures: list[float],
        lagged: list[float],
        creep_force: CreepForce,
    ) -> list[float]:
        """The wheelsets' share of Q (a list of floats), their terms and slopes into ``s``."""
        (
            static_load,
            contact_stiffness,
            contact_damping,
            radius,
            beta,
            brake_gain_m3,
            rolling_coefficient,
            max_torque,
            max_power,
        ) = self._constants
        pitch_speed = v[_BOGIE_PITCH]
        forces = [0.0] * DOF
        for axle, (ix, iz, ispin) in enumerate(_WHEELSETS):
            normal = static_load - contact_stiffness * q[iz] - contact_damping * v[iz]
            spin = v[ispin]
            slip = v[ix] - radius * spin
            creep, creep_slope = creep_force(slip, v[ix], normal)
            relative_spin = spin + pitch_speed
            brake_gain = brake_gain_m3 * pressures[axle]
            brake = -brake_gain * saturated_sign(relative_spin, beta)
            rolling_gain = max(normal, 0.0) * radius * rolling_coefficient
            rolling = -rolling_gain * saturated_sign(spin, beta)
            limit = max_torque
            speed = abs(spin)
            if speed * limit > max_power:
                limit = max_power / speed
            motor = min(max(lagged[axle], -limit), limit)
            forces[ix] += creep
            forces[ispin] += motor + brake + rolling - radius * creep
            forces[_BOGIE_PITCH] += motor + brake
            s.creep[axle], s.creep_slope[axle], s.slip[axle] = creep, creep_slope, slip
            s.brake[axle] = brake
            s.brake_slope[axle] = -brake_gain / beta if abs(relative_spin) < beta else 0.0
            s.rolling[axle] = rolling
            s.rolling_slope[axle] = -rolling_gain / beta if speed < beta else 0.0
            s.motor[axle], s.normal[axle] = motor, normal
        return forces


class BogieModel:
    """Truth of the vehicle on its bogie; ``step`` integrates, ``truth`` reports.

    Parameters
    ----------
    parameters : BogieParameters
    position_m : float
        Initial position [m] of the bogie centre along the line.
    speed_mps : float
        Initial speed [m/s], every body moving together, wheels rolling without creep.
    max_substep_s : float
        Largest integration substep [s].
    integrator : {"linearly_implicit", "forward_euler"}
        The default, or the seed's explicit scheme (needs substeps of about 1e-4 s).
    """

    def __init__(
        self,
        parameters: BogieParameters = URV_BOGIE_PARAMETERS,
        *,
        position_m: float = 0.0,
        speed_mps: float = 0.0,
        max_substep_s: float = DEFAULT_SUBSTEP_S,
        integrator: Integrator = "linearly_implicit",
    ) -> None:
        if max_substep_s <= 0.0:
            raise ValueError("max_substep_s must be positive")
        self.parameters = parameters
        self.integrator: Integrator = integrator
        self.max_substep_s = max_substep_s
        self.matrices = assemble_matrices(parameters)
        self._mass_inverse = np.linalg.inv(self.matrices.mass)
        self._systems: dict[float, tuple[Matrix, Matrix, list[float]]] = {}
        self._origin_m = position_m
        self._q = np.zeros(DOF)
        self._v = np.zeros(DOF)
        self._v[[0, 4, 7]] = speed_mps
        self._v[[6, 9]] = speed_mps / parameters.wheel_radius_m
        self._time_s = 0.0
        self._acceleration_mps2 = 0.0
        self._motor_lagged_nm = [0.0, 0.0]
        self._pressure_pa = [0.0, 0.0]
        self._state = _Linearised()
        self._creep_force: tuple[float, CreepForce] = (
            1.0,
            creep_force_function(parameters.contact),
        )
        """The creep force at an adhesion factor, the last asked for."""
        self._carbody_longitudinal: list[float] = self.matrices.carbody_longitudinal.tolist()
        self._air_speed_of: tuple[Matrix | None, float] = (None, 0.0)
        """A velocity vector and its carbody's air speed [m/s], the last worked out: the next
        evaluation reads the velocity that the last substep's bookkeeping made."""
        self._wheelsets = _WheelsetForces(parameters)
        self._traction_j = 0.0
        self._regen_j = 0.0
        self._losses = {"damping": 0.0, "creep": 0.0, "rolling": 0.0, "brake": 0.0, "aero": 0.0}
        self._gravity_work_j = 0.0
        self._initial_mechanical_j = self._kinetic_j() + self._elastic_j()
        self._evaluate(_Gravity(self.matrices, 0.0, 0.0), 1.0)

    # -- public -------------------------------------------------------------------------------

    def step(
        self,
        dt_s: float,
        commands: ActuatorCommands,
        *,
        gradient_permille: float = 0.0,
        adhesion_factor: float = 1.0,
    ) -> None:
        """Advance by ``dt_s`` [s] under the actuator references, on a gradient [‰] (positive
        uphill when running forwards) with μ₀ scaled by ``adhesion_factor``."""
        if dt_s <= 0.0:
            raise ValueError("dt_s must be positive")
        count = max(1, math.ceil(dt_s / self.max_substep_s - 1e-9))
        h = dt_s / count
        angle = math.atan(gradient_permille / 1000.0)
        sin_a, cos_a = math.sin(angle), math.cos(angle)
        speed_before = float(self._v[0])
        torques = (commands.motor_torque_front_nm, commands.motor_torque_rear_nm)
        pressures = (commands.brake_pressure_front_pa, commands.brake_pressure_rear_pa)
        substep = self._implicit if self.integrator == "linearly_implicit" else self._explicit
        gravity = _Gravity(self.matrices, sin_a, cos_a)
        for _ in range(count):
            self._lag_actuators(h, torques, pressures)
            self._evaluate(gravity, adhesion_factor)
            substep(h, gravity)
            self._time_s += h
        self._acceleration_mps2 = (float(self._v[0]) - speed_before) / dt_s
        self._evaluate(gravity, adhesion_factor)

    def truth(self) -> BogieTruth:
        """The state and what the model did, as of the end of the last step."""
        p = self.parameters
        v = self._v
        s = self._state
        return BogieTruth(
            time_s=self._time_s,
            position_m=self._origin_m + float(self._q[0]),
            speed_mps=float(v[0]),
            acceleration_mps2=self._acceleration_mps2,
            wheel_speed_front_radps=float(v[6]),
            wheel_speed_rear_radps=float(v[9]),
            wheel_radius_m=p.wheel_radius_m,
            motor_torque_front_nm=s.motor[0],
            motor_torque_rear_nm=s.motor[1],
            brake_torque_front_nm=s.brake[0],
            brake_torque_rear_nm=s.brake[1],
            normal_force_front_n=s.normal[0],
            normal_force_rear_n=s.normal[1],
            creepage_front=creepage(s.slip[0], float(v[4])),
            creepage_rear=creepage(s.slip[1], float(v[7])),
            traction_energy_j=self._traction_j,
            regen_energy_j=self._regen_j,
        )

    def energy(self) -> BogieEnergy:
        """Energy bookkeeping since creation, for balance checks."""
        losses = self._losses
        return BogieEnergy(
            motor_work_j=self._traction_j - self._regen_j,
            kinetic_j=self._kinetic_j(),
            elastic_j=self._elastic_j(),
            gravity_work_j=self._gravity_work_j,
            damping_j=losses["damping"],
            creep_j=losses["creep"],
            rolling_j=losses["rolling"],
            brake_j=losses["brake"],
            aerodynamic_j=losses["aero"],
            initial_mechanical_j=self._initial_mechanical_j,
        )

    # -- forces -------------------------------------------------------------------------------

    def _lag_actuators(
        self, h: float, torques: tuple[float, float], pressures: tuple[float, float]
    ) -> None:
        p = self.parameters
        # Exact discretisation of the first-order lags: the same response at any substep.
        motor_blend = -math.expm1(-h / p.motor_time_constant_s)
        brake_blend = -math.expm1(-h / p.brake_time_constant_s)
        for axle in (0, 1):
            self._motor_lagged_nm[axle] += (
                torques[axle] - self._motor_lagged_nm[axle]
            ) * motor_blend
            reference = min(max(pressures[axle], 0.0), p.brake_max_pressure_pa)
            self._pressure_pa[axle] += (reference - self._pressure_pa[axle]) * brake_blend

    def _evaluate(self, gravity: _Gravity, adhesion_factor: float) -> None:
        """Fill ``self._state`` with Q and its stiff slopes at the current state."""
        p = self.parameters
        m = self.matrices
        s = self._state
        v = self._v.tolist()
        if adhesion_factor != self._creep_force[0]:
            self._creep_force = (adhesion_factor, creep_force_function(p.contact, adhesion_factor))
        forces = self._wheelsets.forces(
            s, self._q.tolist(), v, self._pressure_pa, self._motor_lagged_nm, self._creep_force[1]
        )
        known_v, known_air_speed = self._air_speed_of
        if known_v is self._v:  # worked out by the last substep's bookkeeping
            air_speed = known_air_speed
        else:
            air_speed = float(m.carbody_longitudinal @ self._v)
            self._air_speed_of = (self._v, air_speed)
        s.velocities = v
        dynamic = 0.5 * p.air_density_kgpm3 * air_speed * abs(air_speed)
        s.drag = dynamic * p.drag_area_m2
        s.lift = abs(dynamic) * p.lift_area_m2
        forces[1] += s.lift
        # Q less the drag and gravity, element by element as floats: the same operations, in
        # the same order, as the arrays' (one rounding each), without four arrays made.
        drag = s.drag
        s.forces = np.array(
            [
                force - drag * longitudinal - along + normal
                for force, longitudinal, along, normal in zip(
                    forces, self._carbody_longitudinal, gravity.along, gravity.normal, strict=True
                )
            ]
        )

    # -- integration --------------------------------------------------------------------------

    def _system(self, h: float) -> tuple[Matrix, Matrix, list[float]]:
        """(M + hC + h²K, C + hK) for this substep, computed once per substep length, and the
        first's entries as floats (row by row)."""
        cached = self._systems.get(h)
        if cached is None:
            m = self.matrices
            base = m.mass + h * m.damping + h * h * m.stiffness
            cached = (base, m.damping + h * m.stiffness, base.ravel().tolist())
            self._systems[h] = cached
        return cached

    def _implicit(self, h: float, gravity: _Gravity) -> None:
        base, damping_h, entries = self._system(h)
        s = self._state
        radius = self.parameters.wheel_radius_m
        # The stiff slopes enter 13 entries of the system (_STIFF_ENTRIES), each changed by
        # one subtraction or addition as floats, the bogie's pitch by each axle's in turn.
        changed: list[float] = []
        pitch = entries[_PITCH_ENTRY]
        for axle, (ix, _, ispin) in enumerate(_WHEELSETS):
            creep = h * s.creep_slope[axle]
            brake = h * s.brake_slope[axle]
            changed += (
                entries[ix * DOF + ix] - creep,
                entries[ix * DOF + ispin] + radius * creep,
                entries[ispin * DOF + ix] + radius * creep,
                entries[ispin * DOF + ispin]
                - (radius * radius * creep + brake + h * s.rolling_slope[axle]),
                entries[ispin * DOF + _BOGIE_PITCH] - brake,
                entries[_BOGIE_PITCH * DOF + ispin] - brake,
            )
            pitch -= brake
        changed.append(pitch)
        system = base.copy()
        system.put(_STIFF_ENTRIES, changed)
        rhs = h * (s.forces - damping_h @ self._v - self.matrices.stiffness @ self._q)
        velocity = self._v + _solve(system, rhs)
        self._account(h, velocity, gravity, linearised=True)
        self._v = velocity
        self._q = self._q + h * velocity

    def _explicit(self, h: float, gravity: _Gravity) -> None:
        m = self.matrices
        s = self._state
        acceleration = self._mass_inverse @ (s.forces - m.damping @ self._v - m.stiffness @ self._q)
        velocity = self._v + h * acceleration
        self._account(h, self._v, gravity, linearised=False)
        self._q = self._q + h * self._v
        self._v = velocity

    def _account(self, h: float, velocity: Matrix, gravity: _Gravity, *, linearised: bool) -> None:
        """Add this substep's work of every force, evaluated with the substep's velocities."""
        s = self._state
        m = self.matrices
        radius = self.parameters.wheel_radius_m
        v = velocity.tolist()
        old = s.velocities  # self._v's, as the substep's evaluation read them
        losses = self._losses
        weight = 1.0 if linearised else 0.0
        for axle, (ix, _, ispin) in enumerate(_WHEELSETS):
            relative_spin = v[ispin] + v[_BOGIE_PITCH]
            work = s.motor[axle] * relative_spin * h
            if work >= 0.0:
                self._traction_j += work
            else:
                self._regen_j -= work
            slip = v[ix] - radius * v[ispin]
            creep = s.creep[axle] + weight * s.creep_slope[axle] * (slip - s.slip[axle])
            losses["creep"] -= creep * slip * h
            old_relative = old[ispin] + old[_BOGIE_PITCH]
            brake_change = s.brake_slope[axle] * (relative_spin - old_relative)
            losses["brake"] -= (s.brake[axle] + weight * brake_change) * relative_spin * h
            rolling_change = s.rolling_slope[axle] * (v[ispin] - old[ispin])
            losses["rolling"] -= (s.rolling[axle] + weight * rolling_change) * v[ispin] * h
        air_speed = float(m.carbody_longitudinal @ velocity)
        self._air_speed_of = (velocity, air_speed)
        losses["aero"] += (s.drag * air_speed - s.lift * v[1]) * h
        losses["damping"] += float(velocity @ m.damping @ velocity) * h
        self._gravity_work_j += float(gravity.force @ velocity) * h

    def _kinetic_j(self) -> float:
        return 0.5 * float(self._v @ self.matrices.mass @ self._v)

    def _elastic_j(self) -> float:
        return 0.5 * float(self._q @ self.matrices.stiffness @ self._q)
