"""Remote-driving (RD) speed controller of seed 000: PID with feedforward.

    u = k_p e + k_i ∫e + k_d ė + M g sin ᾱ + M f_v cos ᾱ,    e = v_ref − v

The reference speed ramps towards the operator's target at a comfortable acceleration, so the
controller follows a manoeuvre rather than a step. Integration stops while u saturates
(anti-windup). Gains are constant here; scheduling them on v_ref is the ADF issue's work.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from onboard.plant.point_mass import GRAVITY_MPS2

__all__ = ["RemoteDrivingController", "RemoteDrivingGains"]


@dataclass(frozen=True, kw_only=True)
class RemoteDrivingGains:
    kp_n_per_mps: float = 12_000.0
    ki_n_per_m: float = 1_500.0
    kd_n_s_per_mps: float = 0.0
    reference_acceleration_mps2: float = 0.5
    reference_deceleration_mps2: float = 0.6


class RemoteDrivingController:
    """Tracks a target speed; ``step`` returns the force demand [N]."""

    def __init__(
        self,
        *,
        mass_kg: float,
        rolling_coefficient: float,
        gains: RemoteDrivingGains | None = None,
    ) -> None:
        self.mass_kg = mass_kg
        self.rolling_coefficient = rolling_coefficient
        self.gains = gains or RemoteDrivingGains()
        self.reference_speed_mps = 0.0
        self._integral = 0.0
        self._previous_error: float | None = None

    def reset(self, speed_mps: float) -> None:
        """Start from the current speed, with no accumulated error."""
        self.reference_speed_mps = speed_mps
        self._integral = 0.0
        self._previous_error = None

    def step(
        self,
        dt_s: float,
        *,
        target_speed_mps: float,
        speed_mps: float,
        gradient_permille: float,
        force_limits_n: tuple[float, float],
    ) -> float:
        g = self.gains
        delta = target_speed_mps - self.reference_speed_mps
        ramp = g.reference_acceleration_mps2 if delta > 0 else g.reference_deceleration_mps2
        self.reference_speed_mps += max(-ramp * dt_s, min(ramp * dt_s, delta))

        error = self.reference_speed_mps - speed_mps
        derivative = 0.0 if self._previous_error is None else (error - self._previous_error) / dt_s
        self._previous_error = error
        slope = math.atan(gradient_permille / 1000.0)
        feedforward = (
            self.mass_kg
            * GRAVITY_MPS2
            * (math.sin(slope) + self.rolling_coefficient * math.cos(slope))
        )
        candidate_integral = self._integral + error * dt_s
        demand = (
            g.kp_n_per_mps * error
            + g.ki_n_per_m * candidate_integral
            + g.kd_n_s_per_mps * derivative
            + feedforward
        )
        low, high = force_limits_n
        if low < demand < high:
            self._integral = candidate_integral
        if target_speed_mps == 0.0 and self.reference_speed_mps == 0.0 and speed_mps < 0.05:
            self._integral = 0.0
            return low  # hold the stopped vehicle with the brake
        return min(max(demand, low), high)
