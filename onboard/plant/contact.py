"""Wheel–rail longitudinal contact of the bogie model (seed 003 §5.5–5.6).

The longitudinal creep force follows Polach's method as the seed writes it (eq. 19–22):

    F_L = F_N (2μ/π) (k_A ε / (1 + (k_A ε)²) + arctan(k_S ε)),
    ε = G π a b C₁₁ |ξ| / (4 F_N μ),    ξ = (ẋ − θ̇R) / max(|ẋ|, 0.1),
    μ = μ₀ ((1 − A) e^{−B w_s} + A),

with w_s = |ẋ − θ̇R| the sliding speed. The force opposes the slip: a wheel that spins faster
than it rolls (traction) is pushed forwards. One wheelset's two wheel–rail contacts are lumped
into one with the wheelset's total normal load; with equal loads this is exact, because ε scales
with a b / F_N per wheel.

The functions here return the force together with its derivative with respect to the slip
velocity, which the bogie model's linearly implicit integrator needs: at low speed the creep
force is the stiffest term of the whole model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

__all__ = [
    "MIN_REFERENCE_SPEED_MPS",
    "PolachParameters",
    "creepage",
    "longitudinal_creep_force",
    "polach_force",
    "saturated_sign",
]

MIN_REFERENCE_SPEED_MPS = 0.1
"""Floor of the creepage's denominator [m/s], seed 003 eq. 21."""


@dataclass(frozen=True, kw_only=True)
class PolachParameters:
    """Polach's creep-force parameters for one wheelset (two wheels), SI units.

    Attributes
    ----------
    static_friction : float
        μ₀, friction coefficient at zero sliding speed.
    friction_ratio_at_infinite_slip : float
        A, ratio of the friction at infinite sliding speed to μ₀.
    friction_decay_s_per_m : float
        B [s/m], exponential decrease of friction with the sliding speed.
    reduction_adhesion_area : float
        k_A, reduction factor in the area of adhesion.
    reduction_slip_area : float
        k_S, reduction factor in the area of slip.
    shear_modulus_pa : float
        G [Pa] of wheel and rail steel.
    contact_half_axes_product_m2 : float
        a·b [m²] of one wheel's Hertzian contact ellipse under the static load.
    kalker_c11 : float
        Kalker's creepage coefficient C₁₁ for that ellipse.
    """

    static_friction: float
    friction_ratio_at_infinite_slip: float
    friction_decay_s_per_m: float
    reduction_adhesion_area: float
    reduction_slip_area: float
    shear_modulus_pa: float
    contact_half_axes_product_m2: float
    kalker_c11: float

    @cached_property
    def creep_coefficient_n(self) -> float:
        """G π a b C₁₁ / 4 for the wheelset's two contacts [N], the numerator of ε."""
        return (
            self.shear_modulus_pa
            * math.pi
            * 2.0
            * self.contact_half_axes_product_m2
            * self.kalker_c11
            / 4.0
        )


def saturated_sign(value: float, saturation: float) -> float:
    """Sign made continuous: ``value / saturation`` clipped to [−1, 1] (seed 003 fig. 8)."""
    ratio = value / saturation
    if ratio > 1.0:
        return 1.0
    if ratio < -1.0:
        return -1.0
    return ratio


def creepage(slip_velocity_mps: float, rolling_speed_mps: float) -> float:
    """Longitudinal creepage ξ = (ẋ − θ̇R) / max(|ẋ|, 0.1), seed 003 eq. 21."""
    return slip_velocity_mps / max(abs(rolling_speed_mps), MIN_REFERENCE_SPEED_MPS)


def longitudinal_creep_force(
    slip_velocity_mps: float,
    rolling_speed_mps: float,
    normal_force_n: float,
    parameters: PolachParameters,
    adhesion_factor: float = 1.0,
) -> tuple[float, float]:
    """Polach's longitudinal creep force on a wheelset and its slope.

    Parameters
    ----------
    slip_velocity_mps : float
        ẋ − θ̇R [m/s]: wheel centre speed minus circumferential speed; negative in traction.
    rolling_speed_mps : float
        ẋ [m/s], the wheel centre's speed along the track.
    normal_force_n : float
        F_N [N], the wheelset's total normal load; no force without contact.
    parameters : PolachParameters
    adhesion_factor : float
        Scales μ₀: 1 on dry rail, lower for a friction drop.

    Returns
    -------
    force_n : float
        F_L [N] on the wheelset along the track, opposite to the slip velocity.
    slope_n_per_mps : float
        ∂F_L/∂(ẋ − θ̇R) [N·s/m] at constant ẋ in the creepage's denominator and constant F_N;
        negative in the adhesion area, towards zero or positive beyond the adhesion peak.
    """
    p = parameters
    return polach_force(
        slip_velocity_mps,
        rolling_speed_mps,
        normal_force_n,
        p.static_friction * adhesion_factor,
        p.friction_ratio_at_infinite_slip,
        p.friction_decay_s_per_m,
        p.creep_coefficient_n,
        p.reduction_adhesion_area,
        p.reduction_slip_area,
    )


def polach_force(
    slip_velocity_mps: float,
    rolling_speed_mps: float,
    normal_force_n: float,
    static_friction: float,
    friction_ratio: float,
    decay_rate: float,
    creep_coefficient_n: float,
    reduction_adhesion: float,
    reduction_slip: float,
) -> tuple[float, float]:
    """:func:`longitudinal_creep_force` on plain floats, μ₀ already scaled by the adhesion
    factor: the one formula, which the bogie's compiled substeps run as well
    (:mod:`onboard.plant.bogie_kernel`), so it uses only what numba compiles."""
    if normal_force_n <= 0.0:
        return 0.0, 0.0
    remainder = 1.0 - friction_ratio
    sliding = abs(slip_velocity_mps)
    decay = math.exp(-decay_rate * sliding)
    friction = static_friction * (remainder * decay + friction_ratio)
    friction_slope = -static_friction * remainder * decay_rate * decay
    reference = max(abs(rolling_speed_mps), MIN_REFERENCE_SPEED_MPS)
    scale = creep_coefficient_n / (reference * normal_force_n * friction)
    eps = scale * sliding
    adhesion = reduction_adhesion * eps
    slip = reduction_slip * eps
    shape = adhesion / (1.0 + adhesion * adhesion) + math.atan(slip)
    shape_slope = reduction_adhesion * (1.0 - adhesion * adhesion) / (
        1.0 + adhesion * adhesion
    ) ** 2 + reduction_slip / (1.0 + slip * slip)
    eps_slope = scale * (1.0 - sliding * friction_slope / friction)
    magnitude = normal_force_n * 2.0 / math.pi * friction * shape
    magnitude_slope = (
        normal_force_n
        * 2.0
        / math.pi
        * (friction_slope * shape + friction * shape_slope * eps_slope)
    )
    return (-magnitude if slip_velocity_mps > 0.0 else magnitude), -magnitude_slope
