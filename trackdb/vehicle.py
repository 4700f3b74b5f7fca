"""The vehicle's data, in one place for both sides: the URV as a point mass.

The onboard plant integrates these parameters (:mod:`onboard.plant.point_mass`), the ADF takes
them as its controllers' model, and the journey planner (:mod:`trackdb.journey`), which also
runs on the trackside, derives from them the limits it plans with. ``trackdb`` is the lowest
package both sides import that holds data about the railway rather than wire contracts, so
the vehicle lives here (docs/decisions.md, "One home for the vehicle's data and the physical
constants").
"""

from __future__ import annotations

from dataclasses import dataclass

from protocol.units import MPS_PER_KMH

__all__ = ["URV_MAX_SPEED_MPS", "URV_PARAMETERS", "PointMassParameters"]


@dataclass(frozen=True, kw_only=True)
class PointMassParameters:
    """A vehicle as a point mass (DOMAIN.md §4), SI units."""

    mass_kg: float
    rotating_mass_factor: float
    """ρ: the rotating parts' inertia as a share of the mass [1]."""
    davis_a_n: float
    davis_b_n_per_mps: float
    davis_c_n_per_mps2: float
    max_traction_force_n: float
    max_traction_power_w: float
    max_brake_force_n: float
    actuator_time_constant_s: float


URV_PARAMETERS = PointMassParameters(
    # Assumed values: the seeds give no numbers for the vehicle. Seed 003 describes a single
    # high-speed bogie under a small carbody, "closer to an SUV than a train": we take 15 t.
    mass_kg=15_000.0,
    rotating_mass_factor=0.08,
    # Davis: 1 daN/t for steel wheels on rail, a little mechanical friction, and ½ρ C_d S with
    # ρ = 1.2 kg/m³ and C_d S ≈ 0.67 m² for the SUV-sized body. That is 1.55 kN and 86 kW at
    # 200 km/h: seed 003 §7.2 ends with the 100 kW range extender alone holding 200 km/h, so
    # the cruise load must stay under it (with drive losses and auxiliaries, 99 kW on the bus).
    davis_a_n=150.0,
    davis_b_n_per_mps=3.0,
    davis_c_n_per_mps2=0.40,
    # Two traction motors; power from two 742 V × 200 A packs plus the 100 kW range extender.
    max_traction_force_n=30_000.0,
    max_traction_power_w=400_000.0,
    # Service braking of about 1 m/s².
    max_brake_force_n=15_000.0,
    actuator_time_constant_s=0.3,
)

URV_MAX_SPEED_MPS = 200.0 * MPS_PER_KMH
"""The URV's maximum speed: 200 km/h (seed 003 §7.2 holds it) [m/s]."""
