"""Blended braking, seed 003 §3.2: electric first, then electric + pneumatic, then pneumatic.

The braking torque demand T_b,ref is split as T_e = k_e T_b,ref and T_p = k_p T_b,ref
(seed 003 eq. 2). k_e falls with speed between ``blending_speed_mps`` and
``min_electric_braking_speed_mps`` (fig. 4b) and with SOC between ``regen_full_soc`` and
``regen_zero_soc`` (fig. 4c); the electric torque is further capped by the drives' torque–speed
curve and by the power the battery may take (BMS charge limit). The pneumatic brake takes
whatever the electric brake does not, so k_p = 1 − (achieved electric share) and the sum meets
the demand in steady state up to the pneumatic brake's maximum.
"""

from __future__ import annotations

from dataclasses import dataclass

from onboard.vcu.parameters import BrakingPhase, VcuParameters
from onboard.vcu.traction import motor_torque_limit_nm

__all__ = ["BlendedBraking", "BrakingSplit", "electric_share"]


def _fraction(value: float, zero_at: float, full_at: float) -> float:
    if zero_at == full_at:
        return 1.0 if value >= full_at else 0.0
    return min(max((value - zero_at) / (full_at - zero_at), 0.0), 1.0)


def electric_share(speed_mps: float, soc: float, parameters: VcuParameters) -> float:
    """k_e [0, 1] from speed [m/s] and SOC [fraction], before the power and torque caps."""
    by_speed = _fraction(
        speed_mps, parameters.min_electric_braking_speed_mps, parameters.blending_speed_mps
    )
    by_soc = _fraction(soc, parameters.regen_zero_soc, parameters.regen_full_soc)
    return by_speed * by_soc


@dataclass(frozen=True, slots=True)
class BrakingSplit:
    """Braking torques for the vehicle [N·m] (positive magnitudes) and the phase."""

    electric_nm: float
    pneumatic_nm: float
    phase: BrakingPhase
    limited_by_soc: bool


class BlendedBraking:
    """Splits a braking torque demand between the drives and the pneumatic brakes."""

    def __init__(self, parameters: VcuParameters) -> None:
        self.parameters = parameters

    def phase(self, speed_mps: float) -> BrakingPhase:
        """The phase of seed 003 §3.2 by speed alone."""
        p = self.parameters
        if speed_mps >= p.blending_speed_mps:
            return BrakingPhase.ELECTRIC
        if speed_mps > p.min_electric_braking_speed_mps:
            return BrakingPhase.BLENDED
        return BrakingPhase.PNEUMATIC

    def split(
        self,
        demand_nm: float,
        *,
        speed_mps: float,
        wheel_speeds_radps: tuple[float, float],
        soc: float,
        max_regen_power_w: float,
    ) -> BrakingSplit:
        """Split ``demand_nm`` [N·m] (≥ 0, whole vehicle at the wheelsets).

        ``max_regen_power_w`` [W] is the mechanical power the drives may take at the wheels:
        the BMS charge limit plus the load of auxiliaries and range extender, over the drive
        efficiency. The caller works it out.
        """
        p = self.parameters
        share = electric_share(speed_mps, soc, p)
        by_speed = electric_share(speed_mps, 0.0, p)
        torque_cap = sum(motor_torque_limit_nm(w, p) for w in wheel_speeds_radps)
        omega = max(speed_mps / p.wheel_radius_m, 1e-6)
        power_cap = max(max_regen_power_w, 0.0) / omega
        electric = min(share * demand_nm, torque_cap, power_cap)
        pneumatic_cap = 2.0 * p.brake_gain_nm_per_pa * p.max_brake_pressure_pa
        pneumatic = min(demand_nm - electric, pneumatic_cap)
        return BrakingSplit(
            electric_nm=electric,
            pneumatic_nm=pneumatic,
            phase=self.phase(speed_mps),
            limited_by_soc=electric < by_speed * demand_nm - 1e-9,
        )
