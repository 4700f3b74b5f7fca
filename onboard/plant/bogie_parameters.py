"""Parameters and linear matrices of the planar 10-DOF bogie model (seed 003 §5.1–5.3).

Generalised coordinates, in the track's frame (x along the track, z normal to it, upwards;
pitch θ positive nose-up, wheel spin φ positive when rolling forwards)::

    0 x_b   bogie longitudinal       5 z_f  front wheelset vertical
    1 z_b   bogie vertical           6 φ_f  front wheelset spin
    2 θ_b   bogie pitch              7 x_r  rear wheelset longitudinal
    3 θ_c   carbody pitch            8 z_r  rear wheelset vertical
    4 x_f   front wheelset long.     9 φ_r  rear wheelset spin

Vertical coordinates are measured from the static equilibrium on level track, so that gravity's
normal component and the springs' preloads cancel; longitudinal coordinates share one origin
(each wheelset's x is its axle position less its nominal offset from the bogie centre). As in
the seed, the carbody is pinned to the bogie: its longitudinal and vertical motion follow the
bogie, and its pitch is held by the secondary springs. [M], [K], [C] are built from Jacobians
(seed eq. 5, 8, 11); the wheel–rail normal contact is a linear spring-damper (eq. 18) and so
belongs to [K] and [C] as well.

The seed gives the structure but almost no numbers. Every value below is an assumption for a
15 t vehicle on one high-speed bogie (wheelbase 2.5 m, from the seed), chosen to agree with
:data:`onboard.plant.point_mass.URV_PARAMETERS` (mass, rotating-mass factor, Davis
coefficients, traction envelope), or taken from the literature where named.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from onboard.plant.contact import PolachParameters
from protocol.units import GRAVITY_MPS2
from trackdb.vehicle import URV_PARAMETERS

__all__ = [
    "DOF",
    "URV_BOGIE_PARAMETERS",
    "BogieMatrices",
    "BogieParameters",
    "assemble_matrices",
]

DOF = 10
Matrix = NDArray[np.float64]

POLACH_DRY_RAIL = PolachParameters(
    # Polach (Wear 258, 2005), the dry-rail parameter set, quoted from memory.
    static_friction=0.55,
    friction_ratio_at_infinite_slip=0.40,
    friction_decay_s_per_m=0.60,
    reduction_adhesion_area=1.00,
    reduction_slip_area=0.40,
    shear_modulus_pa=8.1e10,
    # Assumed: Hertzian half-axes of about 6 mm x 4.3 mm for a 920 mm wheel on a UIC 60 rail
    # under the static wheel load (~37 kN), and Kalker's C11 for that ellipse (ν ≈ 0.28).
    contact_half_axes_product_m2=2.6e-5,
    kalker_c11=4.12,
)


def _wheelset_inertia() -> float:
    # Two wheelsets' J/R² make up the point-mass model's rotating-mass factor.
    radius = 0.46
    return URV_PARAMETERS.rotating_mass_factor * URV_PARAMETERS.mass_kg * radius**2 / 2.0


@dataclass(frozen=True, kw_only=True)
class BogieParameters:
    """Physical parameters of the bogie model, SI units. Sources in the comments of the default."""

    bogie_mass_kg: float
    bogie_pitch_inertia_kgm2: float
    carbody_mass_kg: float
    carbody_pitch_inertia_kgm2: float
    wheelset_mass_kg: float
    wheelset_spin_inertia_kgm2: float
    wheel_radius_m: float
    half_wheelbase_m: float
    bogie_centre_above_axle_m: float
    pin_above_bogie_centre_m: float
    carbody_centre_above_pin_m: float
    secondary_half_spacing_m: float
    primary_longitudinal_stiffness_n_per_m: float
    primary_longitudinal_damping_ns_per_m: float
    primary_vertical_stiffness_n_per_m: float
    primary_vertical_damping_ns_per_m: float
    secondary_vertical_stiffness_n_per_m: float
    secondary_vertical_damping_ns_per_m: float
    contact_stiffness_n_per_m: float
    contact_damping_ns_per_m: float
    bearing_damping_nms_per_rad: float
    rolling_resistance_coefficient: float
    drag_area_m2: float
    lift_area_m2: float
    air_density_kgpm3: float
    motor_max_torque_nm: float
    motor_max_power_w: float
    motor_time_constant_s: float
    brake_gain_m3: float
    brake_max_pressure_pa: float
    brake_time_constant_s: float
    sign_saturation_radps: float
    contact: PolachParameters = field(default=POLACH_DRY_RAIL)

    @cached_property
    def total_mass_kg(self) -> float:
        return self.bogie_mass_kg + self.carbody_mass_kg + 2.0 * self.wheelset_mass_kg

    @cached_property
    def static_axle_load_n(self) -> float:
        """F_N0 of one wheelset on level track [N]; the layout is symmetric fore and aft."""
        return self.total_mass_kg * GRAVITY_MPS2 / 2.0


_RADIUS_M = 0.46
_AXLE_LOAD_N = URV_PARAMETERS.mass_kg * GRAVITY_MPS2 / 2.0

URV_BOGIE_PARAMETERS = BogieParameters(
    # Masses: 15 t in all as URV_PARAMETERS; split assumed for a high-speed bogie frame with its
    # two traction motors and gearboxes (3.8 t), two wheelsets with brake discs (1.6 t each) and
    # the small carbody with batteries, range extender and instruments (8 t).
    bogie_mass_kg=3_800.0,
    bogie_pitch_inertia_kgm2=2_100.0,
    carbody_mass_kg=8_000.0,
    # Assumed: a 4 m x 2 m box, m (L² + H²) / 12.
    carbody_pitch_inertia_kgm2=13_300.0,
    wheelset_mass_kg=1_600.0,
    wheelset_spin_inertia_kgm2=_wheelset_inertia(),
    # 920 mm wheels, usual for high-speed bogies; wheelbase 2.5 m from seed 003 §1.
    wheel_radius_m=_RADIUS_M,
    half_wheelbase_m=1.25,
    # Assumed heights: bogie centre of gravity 0.65 m above the rail, carbody pin 0.35 m above
    # it, carbody centre of gravity 0.85 m above the pin (1.85 m above the rail).
    bogie_centre_above_axle_m=0.65 - _RADIUS_M,
    pin_above_bogie_centre_m=0.35,
    carbody_centre_above_pin_m=0.85,
    secondary_half_spacing_m=1.5,
    # Suspension per wheelset (two axle boxes) or per side, assumed typical of high-speed
    # bogies: stiff longitudinal bushings, soft primary coil springs, air-spring-like secondary.
    primary_longitudinal_stiffness_n_per_m=2.0e7,
    primary_longitudinal_damping_ns_per_m=2.0e4,
    primary_vertical_stiffness_n_per_m=1.8e6,
    primary_vertical_damping_ns_per_m=2.0e4,
    secondary_vertical_stiffness_n_per_m=4.0e5,
    secondary_vertical_damping_ns_per_m=3.0e4,
    # Linearised Hertzian stiffness of two wheel–rail contacts (~1.2e9 N/m each) and a damping
    # ratio of about 0.1 on the wheelset's contact mode, which keeps the seed's forward Euler at
    # 1e-4 s stable as the seed reports.
    contact_stiffness_n_per_m=2.4e9,
    contact_damping_ns_per_m=3.9e5,
    # Davis B of URV_PARAMETERS (3 N per m/s) as viscous losses in the two axles' bearings
    # and gearboxes: torque c ω, force c v / R² per axle.
    bearing_damping_nms_per_rad=URV_PARAMETERS.davis_b_n_per_mps * _RADIUS_M**2 / 2.0,
    # Davis A of URV_PARAMETERS (150 N on 15 t) as rolling resistance f_v = A / (m g).
    rolling_resistance_coefficient=URV_PARAMETERS.davis_a_n
    / (URV_PARAMETERS.mass_kg * GRAVITY_MPS2),
    # Davis C of URV_PARAMETERS: ½ ρ C_d S = 0.40 N/(m/s)² with ρ = 1.2 kg/m³. The lift area is
    # assumed (the seed's CFD value is not given): a small upwards lift.
    drag_area_m2=2.0 * URV_PARAMETERS.davis_c_n_per_mps2 / 1.2,
    lift_area_m2=0.4,
    air_density_kgpm3=1.2,
    # 30 kN and 400 kW at the wheels for the two motors together (URV_PARAMETERS); the drive's
    # time constant is assumed.
    motor_max_torque_nm=URV_PARAMETERS.max_traction_force_n / 2.0 * _RADIUS_M,
    motor_max_power_w=URV_PARAMETERS.max_traction_power_w / 2.0,
    motor_time_constant_s=0.05,
    # Assumed: 4 bar of cylinder pressure gives 9 kN per wheelset (1.2 m/s² with both), and
    # a pneumatic time constant of 0.5 s.
    brake_gain_m3=9_000.0 * _RADIUS_M / 4.0e5,
    brake_max_pressure_pa=4.0e5,
    brake_time_constant_s=0.5,
    # β of seed fig. 8 for the brake and rolling-resistance torques: small enough that a braked
    # vehicle on a gradient creeps by millimetres per minute.
    sign_saturation_radps=1.0e-3,
)
if abs(URV_BOGIE_PARAMETERS.static_axle_load_n - _AXLE_LOAD_N) > 1e-6:
    raise ValueError("the bogie model's mass must match URV_PARAMETERS")


@dataclass(frozen=True)
class BogieMatrices:
    """[M], [K], [C] (10 x 10) and the constant vectors of the generalised forces."""

    mass: Matrix
    stiffness: Matrix
    damping: Matrix
    gravity_along_track: Matrix
    """Generalised force of g = 1 m/s² pulling every body forwards along the track."""
    gravity_normal: Matrix
    """Generalised force of g = 1 m/s² pulling every body towards the track."""
    carbody_longitudinal: Matrix
    """Row of the mass Jacobian for the carbody's centre, where drag acts."""


def _mass_jacobian(p: BogieParameters) -> tuple[Matrix, Matrix]:
    """λ_m (12 x 10) over bodies' x, z, rotation, and the diagonal [m] (seed eq. 5–6)."""
    jac = np.zeros((12, DOF))
    # bogie x, z, θ
    jac[0, 0] = jac[1, 1] = jac[2, 2] = 1.0
    # carbody x, z, θ: its centre sits above the pin, which sits above the bogie's centre.
    jac[3, 0] = 1.0
    jac[3, 2] = -p.pin_above_bogie_centre_m
    jac[3, 3] = -p.carbody_centre_above_pin_m
    jac[4, 1] = 1.0
    jac[5, 3] = 1.0
    for row, column in zip(range(6, 12), range(4, 10), strict=True):
        jac[row, column] = 1.0
    masses = np.array(
        [
            p.bogie_mass_kg,
            p.bogie_mass_kg,
            p.bogie_pitch_inertia_kgm2,
            p.carbody_mass_kg,
            p.carbody_mass_kg,
            p.carbody_pitch_inertia_kgm2,
        ]
        + [p.wheelset_mass_kg, p.wheelset_mass_kg, p.wheelset_spin_inertia_kgm2] * 2
    )
    return jac, masses


def _element_jacobian(p: BogieParameters) -> Matrix:
    """λ_k: one row per spring/damper element's deflection (seed eq. 10, plus contact, bearings)."""
    a, h = p.half_wheelbase_m, p.bogie_centre_above_axle_m
    l2 = p.secondary_half_spacing_m
    jac = np.zeros((10, DOF))
    jac[0, [0, 2, 4]] = [-1.0, -h, 1.0]  # front bushing: axle x less the bogie's axle box x
    jac[1, [0, 2, 7]] = [-1.0, -h, 1.0]  # rear bushing
    jac[2, [1, 2, 5]] = [1.0, a, -1.0]  # front primary spring: bogie box z less axle z
    jac[3, [1, 2, 8]] = [1.0, -a, -1.0]  # rear primary spring
    jac[4, [2, 3]] = [-l2, l2]  # front secondary spring
    jac[5, [2, 3]] = [l2, -l2]  # rear secondary spring
    jac[6, 5] = 1.0  # front wheel–rail contact
    jac[7, 8] = 1.0  # rear wheel–rail contact
    jac[8, [2, 6]] = [1.0, 1.0]  # front axle spin relative to the bogie (bearings, gearbox)
    jac[9, [2, 9]] = [1.0, 1.0]  # rear axle
    return jac


def assemble_matrices(p: BogieParameters) -> BogieMatrices:
    """Build [M] = λ_mᵀ[m]λ_m, [K] = λ_kᵀ[k]λ_k, [C] = λ_kᵀ[c]λ_k and the force vectors."""
    mass_jac, masses = _mass_jacobian(p)
    element_jac = _element_jacobian(p)
    stiffness = np.array(
        [p.primary_longitudinal_stiffness_n_per_m] * 2
        + [p.primary_vertical_stiffness_n_per_m] * 2
        + [p.secondary_vertical_stiffness_n_per_m] * 2
        + [p.contact_stiffness_n_per_m] * 2
        + [0.0, 0.0]
    )
    damping = np.array(
        [p.primary_longitudinal_damping_ns_per_m] * 2
        + [p.primary_vertical_damping_ns_per_m] * 2
        + [p.secondary_vertical_damping_ns_per_m] * 2
        + [p.contact_damping_ns_per_m] * 2
        + [p.bearing_damping_nms_per_rad] * 2
    )
    along = np.zeros(12)
    normal = np.zeros(12)
    along[[0, 3, 6, 9]] = masses[[0, 3, 6, 9]]
    normal[[1, 4, 7, 10]] = -masses[[1, 4, 7, 10]]
    return BogieMatrices(
        mass=mass_jac.T @ np.diag(masses) @ mass_jac,
        stiffness=element_jac.T @ np.diag(stiffness) @ element_jac,
        damping=element_jac.T @ np.diag(damping) @ element_jac,
        gravity_along_track=mass_jac.T @ along,
        gravity_normal=mass_jac.T @ normal,
        carbody_longitudinal=mass_jac[3].copy(),
    )
