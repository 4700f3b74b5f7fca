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
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from onboard.plant.bogie_parameters import (
    DOF,
    URV_BOGIE_PARAMETERS,
    BogieParameters,
    Matrix,
    assemble_matrices,
)
from onboard.plant.contact import creepage
from onboard.plant.interfaces import ActuatorCommands, BogieTruth

if TYPE_CHECKING:
    from types import ModuleType

__all__ = ["DEFAULT_SUBSTEP_S", "BogieEnergy", "BogieModel", "Integrator"]

DEFAULT_SUBSTEP_S = 0.002
"""Largest substep [s] of the linearly implicit scheme; ``step`` splits longer steps evenly."""
Integrator = Literal["linearly_implicit", "forward_euler"]


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


def _kernel() -> ModuleType:
    """The compiled substeps, imported on the first bogie model made: a run on the point-mass
    model does not load numba."""
    from onboard.plant import bogie_kernel

    return bogie_kernel


class BogieModel:
    """Truth of the vehicle on its bogie; ``step`` integrates, ``truth`` reports.

    The arithmetic of a step runs compiled (:mod:`onboard.plant.bogie_kernel`) on the arrays
    this object holds; the object keeps the time, the parameters and the reports.

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
        kernel = self._kernel = _kernel()
        self.parameters = parameters
        self.integrator: Integrator = integrator
        self.max_substep_s = max_substep_s
        m = self.matrices = assemble_matrices(parameters)
        self._matrices = np.stack([m.mass, m.damping, m.stiffness, np.linalg.inv(m.mass)])
        self._vectors = np.stack(
            [m.carbody_longitudinal, m.gravity_along_track, m.gravity_normal]
        ).astype(np.float64)
        self._constants = _constants(parameters)
        self._models: dict[float, tuple[Matrix, Matrix, Matrix, Matrix]] = {}
        self._origin_m = position_m
        self._q = np.zeros(DOF)
        self._v = np.zeros(DOF)
        self._v[[0, 4, 7]] = speed_mps
        self._v[[6, 9]] = speed_mps / parameters.wheel_radius_m
        self._time_s = 0.0
        self._acceleration_mps2 = 0.0
        self._actuators = np.zeros(4)
        """The motors' lagged torque references [N·m], then the cylinders' pressures [Pa]."""
        self._references = np.zeros(4)
        self._terms = np.zeros((2, kernel.TERMS))
        self._loads = np.zeros((3, DOF))
        self._energy = np.zeros(kernel.ENERGY_ENTRIES)
        self._initial_mechanical_j = self._kinetic_j() + self._elastic_j()
        self._state = (self._q, self._v, self._actuators, self._terms, self._loads, self._energy)
        """The arrays a step changes in place (``bogie_kernel.State``)."""
        kernel.evaluate(self._state, self._model(DEFAULT_SUBSTEP_S), (0.0, 1.0), 1.0)

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
        speed_before = float(self._v[0])
        references = self._references
        references[0] = commands.motor_torque_front_nm
        references[1] = commands.motor_torque_rear_nm
        references[2] = commands.brake_pressure_front_pa
        references[3] = commands.brake_pressure_rear_pa
        self._kernel.advance(
            count,
            h,
            references,
            (math.sin(angle), math.cos(angle)),
            adhesion_factor,
            self.integrator == "linearly_implicit",
            self._state,
            self._model(h),
        )
        for _ in range(count):
            self._time_s += h
        self._acceleration_mps2 = (float(self._v[0]) - speed_before) / dt_s

    def truth(self) -> BogieTruth:
        """The state and what the model did, as of the end of the last step."""
        p = self.parameters
        v = self._v.tolist()
        (front, rear) = self._terms.tolist()
        k = self._kernel
        traction, regen = self._energy[[k.TRACTION, k.REGEN]].tolist()
        return BogieTruth(
            time_s=self._time_s,
            position_m=self._origin_m + float(self._q[0]),
            speed_mps=v[0],
            acceleration_mps2=self._acceleration_mps2,
            wheel_speed_front_radps=v[6],
            wheel_speed_rear_radps=v[9],
            wheel_radius_m=p.wheel_radius_m,
            motor_torque_front_nm=front[k.MOTOR],
            motor_torque_rear_nm=rear[k.MOTOR],
            brake_torque_front_nm=front[k.BRAKE],
            brake_torque_rear_nm=rear[k.BRAKE],
            normal_force_front_n=front[k.NORMAL],
            normal_force_rear_n=rear[k.NORMAL],
            creepage_front=creepage(front[k.SLIP], v[4]),
            creepage_rear=creepage(rear[k.SLIP], v[7]),
            traction_energy_j=traction,
            regen_energy_j=regen,
        )

    def energy(self) -> BogieEnergy:
        """Energy bookkeeping since creation, for balance checks."""
        k = self._kernel
        e = self._energy.tolist()
        return BogieEnergy(
            motor_work_j=e[k.TRACTION] - e[k.REGEN],
            kinetic_j=self._kinetic_j(),
            elastic_j=self._elastic_j(),
            gravity_work_j=e[k.GRAVITY_WORK],
            damping_j=e[k.DAMPING_LOSS],
            creep_j=e[k.CREEP_LOSS],
            rolling_j=e[k.ROLLING_LOSS],
            brake_j=e[k.BRAKE_LOSS],
            aerodynamic_j=e[k.AERO_LOSS],
            initial_mechanical_j=self._initial_mechanical_j,
        )

    # -- integration --------------------------------------------------------------------------

    def _model(self, h: float) -> tuple[Matrix, Matrix, Matrix, Matrix]:
        """What a step of substep ``h`` reads (``bogie_kernel.Model``): [M], [C], [K], [M]⁻¹;
        M + hC + h²K and C + hK, computed once per substep length; the vectors; the
        constants."""
        model = self._models.get(h)
        if model is None:
            m = self.matrices
            system = np.stack(
                [m.mass + h * m.damping + h * h * m.stiffness, m.damping + h * m.stiffness]
            )
            model = self._models[h] = (self._matrices, system, self._vectors, self._constants)
        return model

    def _kinetic_j(self) -> float:
        return 0.5 * float(self._v @ self.matrices.mass @ self._v)

    def _elastic_j(self) -> float:
        return 0.5 * float(self._q @ self.matrices.stiffness @ self._q)


def _constants(p: BogieParameters) -> Matrix:
    """The parameters the compiled forces read, in :mod:`onboard.plant.bogie_kernel`'s order."""
    contact = p.contact
    return np.array(
        [
            p.static_axle_load_n,
            p.contact_stiffness_n_per_m,
            p.contact_damping_ns_per_m,
            p.wheel_radius_m,
            p.sign_saturation_radps,
            p.brake_gain_m3,
            p.rolling_resistance_coefficient,
            p.motor_max_torque_nm,
            p.motor_max_power_w,
            contact.static_friction,
            contact.friction_ratio_at_infinite_slip,
            contact.friction_decay_s_per_m,
            contact.creep_coefficient_n,
            contact.reduction_adhesion_area,
            contact.reduction_slip_area,
            p.air_density_kgpm3,
            p.drag_area_m2,
            p.lift_area_m2,
            p.motor_time_constant_s,
            p.brake_time_constant_s,
            p.brake_max_pressure_pa,
        ]
    )
