"""Motor torque management, seed 003 §3.1: front/rear split k_d and slip protection.

The split starts on the axle that trails in the direction of motion (load transfer loads it,
and the free-rolling leading axle then measures the vehicle's speed); the leading axle takes a
growing share with speed, and whatever the trailing axle's torque–speed curve cannot carry.
Slip protection compares each axle's peripheral speed with the GPS-fused vehicle speed and
with the other axle: a slipping axle's torque is cut to zero, then restarted at a fraction of
what it carried and ramped back while adhesion holds.
"""

from __future__ import annotations

from dataclasses import dataclass

from onboard.vcu.parameters import VcuParameters

__all__ = ["AxleSlipProtection", "TorqueSplit", "leading_share", "motor_torque_limit_nm"]

CUTOFF_EPSILON_S = 1e-9
"""Rounding guard on the cut-off countdown (0.3 − 30 × 0.01 is not exactly 0)."""


def leading_share(speed_mps: float, parameters: VcuParameters) -> float:
    """Share [0, 0.5] of the traction torque on the leading axle at ``speed_mps`` [m/s]."""
    start, equal = parameters.split_start_speed_mps, parameters.equal_split_speed_mps
    if speed_mps <= start:
        return 0.0
    if speed_mps >= equal:
        return 0.5
    return 0.5 * (speed_mps - start) / (equal - start)


def motor_torque_limit_nm(wheel_speed_radps: float, parameters: VcuParameters) -> float:
    """Torque–speed curve of one drive at the wheelset [N·m]: min(T_max, P_max / ω)."""
    omega = abs(wheel_speed_radps)
    if omega * parameters.max_motor_torque_nm <= parameters.max_motor_power_w:
        return parameters.max_motor_torque_nm
    return parameters.max_motor_power_w / omega


@dataclass(frozen=True, slots=True)
class AxleTorques:
    """Traction torques [N·m] on the axle trailing and leading in the direction of motion."""

    trailing_nm: float
    leading_nm: float


class TorqueSplit:
    """k_d(speed, direction): the trailing axle first, then both, equal above a speed."""

    def __init__(self, parameters: VcuParameters) -> None:
        self.parameters = parameters

    def split(
        self, torque_nm: float, speed_mps: float, limits_nm: tuple[float, float]
    ) -> AxleTorques:
        """Split a total traction torque [N·m] (≥ 0) given (trailing, leading) limits [N·m]."""
        share = leading_share(speed_mps, self.parameters)
        trailing_limit, leading_limit = limits_nm
        trailing = min((1.0 - share) * torque_nm, trailing_limit)
        leading = min(torque_nm - trailing, leading_limit)
        return AxleTorques(trailing_nm=trailing, leading_nm=leading)

    @staticmethod
    def front_share(trailing_nm: float, leading_nm: float, direction: int) -> float:
        """k_d of seed 003 eq. (1): the front axle's share of the total, by direction."""
        total = trailing_nm + leading_nm
        if total <= 0.0:
            return 0.0 if direction > 0 else 1.0
        front = leading_nm if direction > 0 else trailing_nm
        return front / total


class AxleSlipProtection:
    """Traction cut-off and ramped restart for one axle; ``limit_nm`` caps its torque."""

    def __init__(self, parameters: VcuParameters) -> None:
        self.parameters = parameters
        self.slipping = False
        self.cutoff_remaining_s = 0.0
        self.limit_nm = parameters.max_motor_torque_nm
        self.torque_limit_nm = parameters.max_motor_torque_nm
        self.slip_count = 0

    def detects_slip(
        self, wheel_speed_mps: float, vehicle_speed_mps: float, other_mps: float
    ) -> bool:
        """True when this axle's peripheral speed [m/s] departs from the fused or other axle's."""
        p = self.parameters
        tolerance = max(p.slip_speed_threshold_mps, p.slip_relative_threshold * vehicle_speed_mps)
        off_vehicle = abs(wheel_speed_mps - vehicle_speed_mps) > tolerance
        off_other = wheel_speed_mps - other_mps > tolerance
        return off_vehicle or off_other

    def step(self, dt_s: float, slip: bool, applied_nm: float) -> float:
        """Update with this step's detection; return the torque limit [N·m] for the axle.

        The cut-off holds the torque at zero while the axle slips and for ``slip_cutoff_s``
        after it re-adheres; the limit then restarts at a fraction of ``applied_nm`` [N·m].
        """
        p = self.parameters
        if slip:
            if not self.slipping:
                self.slip_count += 1
                self.limit_nm = p.slip_restart_fraction * abs(applied_nm)
            self.slipping = True
            self.cutoff_remaining_s = p.slip_cutoff_s
            self.torque_limit_nm = 0.0
            return 0.0
        self.slipping = False
        if self.cutoff_remaining_s > CUTOFF_EPSILON_S:
            self.cutoff_remaining_s = max(self.cutoff_remaining_s - dt_s, 0.0)
            self.torque_limit_nm = 0.0
            return 0.0
        rise = p.slip_recovery_rate_per_s * p.max_motor_torque_nm * dt_s
        self.limit_nm = min(self.limit_nm + rise, p.max_motor_torque_nm)
        self.torque_limit_nm = self.limit_nm
        return self.limit_nm
