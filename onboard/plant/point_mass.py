"""The point-mass longitudinal model of seed 000 (DOMAIN.md §4).

    ṗ = v,    M (1 + ρ) v̇ = u − F_r(v) − F_grad(p) − F_curve(p)

with Davis resistance F_r = γ + η v + ι v², F_grad = M g sin(atan(i/1000)) for a gradient i [‰]
and the curve resistance F_curve = M g (800 / R) / 1000 (the Italian k/R with k = 800). The
applied force u follows the demand through a first-order lag and is limited by the traction
envelope (max force, max power) and the brake's max force. The model runs forwards only: a
vehicle that stops is held (as by its parking brake) rather than rolling back.

The parameters and the URV's values are the vehicle's data, shared with the trackside's
planner: they live in :mod:`trackdb.vehicle` and are re-exported here.
"""

from __future__ import annotations

import dataclasses
import math

from protocol.units import GRAVITY_MPS2
from trackdb.vehicle import URV_PARAMETERS, PointMassParameters

__all__ = [
    "GRAVITY_MPS2",
    "URV_PARAMETERS",
    "PointMassModel",
    "PointMassParameters",
    "with_model_mismatch",
]

CURVE_COEFFICIENT_M = 800.0
MIN_POWER_SPEED_MPS = 1.0
"""Below this speed the power limit is not applied (the force limit governs)."""


def with_model_mismatch(
    parameters: PointMassParameters,
    *,
    mass_factor: float = 1.05,
    davis_factors: tuple[float, float, float] = (1.1, 0.9, 1.1),
) -> PointMassParameters:
    """The truth a controller's model does not know exactly (the ADF issue's test case: mass
    +5 %, Davis coefficients ±10 %)."""
    return dataclasses.replace(
        parameters,
        mass_kg=parameters.mass_kg * mass_factor,
        davis_a_n=parameters.davis_a_n * davis_factors[0],
        davis_b_n_per_mps=parameters.davis_b_n_per_mps * davis_factors[1],
        davis_c_n_per_mps2=parameters.davis_c_n_per_mps2 * davis_factors[2],
    )


class PointMassModel:
    """Truth of the vehicle's longitudinal motion; ``step`` integrates one time step."""

    def __init__(
        self,
        parameters: PointMassParameters = URV_PARAMETERS,
        *,
        position_m: float = 0.0,
        speed_mps: float = 0.0,
    ) -> None:
        if speed_mps < 0:
            raise ValueError("the point-mass model runs forwards only")
        self.parameters = parameters
        self.position_m = position_m
        self.speed_mps = speed_mps
        self.acceleration_mps2 = 0.0
        self.applied_force_n = 0.0
        self.traction_energy_j = 0.0

    def force_limits_n(self, speed_mps: float) -> tuple[float, float]:
        """(min, max) applied force [N] at this speed: full brake, full traction."""
        p = self.parameters
        traction = p.max_traction_force_n
        if speed_mps > MIN_POWER_SPEED_MPS:
            traction = min(traction, p.max_traction_power_w / speed_mps)
        return -p.max_brake_force_n, traction

    def resistance_n(self, speed_mps: float, gradient_permille: float, radius_m: float) -> float:
        """Sum of Davis, gradient and curve forces [N] opposing forward motion."""
        p = self.parameters
        davis = p.davis_a_n + p.davis_b_n_per_mps * speed_mps + p.davis_c_n_per_mps2 * speed_mps**2
        grade = p.mass_kg * GRAVITY_MPS2 * math.sin(math.atan(gradient_permille / 1000.0))
        curve = 0.0
        if math.isfinite(radius_m):
            curve = p.mass_kg * GRAVITY_MPS2 * CURVE_COEFFICIENT_M / radius_m / 1000.0
        return davis + grade + curve

    def step(
        self,
        dt_s: float,
        force_demand_n: float,
        *,
        gradient_permille: float = 0.0,
        curve_radius_m: float = math.inf,
        emergency_brake: float = 0.0,
    ) -> None:
        """Advance by ``dt_s`` [s] under a force demand [N] (positive traction, negative brake).

        ``emergency_brake`` is the EB's share of the full brake force, 0 to 1, as the brake
        pipe vents (the Vital Control's valves): it cuts traction at once and brakes at least
        that hard, whatever the demand.
        """
        p = self.parameters
        low, high = self.force_limits_n(self.speed_mps)
        demand = min(max(force_demand_n, low), high)
        blend = dt_s / (p.actuator_time_constant_s + dt_s)
        self.applied_force_n += (demand - self.applied_force_n) * blend
        self.applied_force_n = min(max(self.applied_force_n, low), high)
        if emergency_brake > 0.0:
            pipe_n = min(emergency_brake, 1.0) * p.max_brake_force_n
            self.applied_force_n = min(self.applied_force_n, 0.0, -pipe_n)

        resistance = self.resistance_n(self.speed_mps, gradient_permille, curve_radius_m)
        net = self.applied_force_n - resistance
        acceleration = net / (p.mass_kg * (1.0 + p.rotating_mass_factor))
        speed = self.speed_mps + acceleration * dt_s
        if speed < 0.0:
            # Braking and resistance stop the vehicle within the step; it is then held.
            speed = 0.0
            acceleration = -self.speed_mps / dt_s
        self.position_m += 0.5 * (self.speed_mps + speed) * dt_s
        if self.applied_force_n > 0:
            self.traction_energy_j += self.applied_force_n * 0.5 * (self.speed_mps + speed) * dt_s
        self.speed_mps = speed
        self.acceleration_mps2 = acceleration
