"""Remote-driving (RD) speed controller of seed 000: gain-scheduled PID with feedforward.

    u = k_p(σ) e + k_i(σ) ∫e + k_d(σ) ė + M g sin ᾱ + M f_v cos ᾱ,    e = v_ref − v,  σ = v_ref

The gains come from a table over the scheduling variable σ = v_ref, interpolated linearly and
held at the ends. The reference speed ramps towards the operator's target at a comfortable
acceleration, so the controller follows a manoeuvre rather than a step; ᾱ is the gradient at
the reference position. Integration stops while u saturates, and while the speed lags the
reference by more than a band (anti-windup: the lag of a power-limited climb to the target is
not stored, to come out as an overshoot). :meth:`align` makes the controller's output equal a
given force, for a bumpless hand-over from the AD controller.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

from protocol.units import GRAVITY_MPS2

__all__ = ["DEFAULT_GAIN_TABLE", "GainPoint", "RemoteDrivingController", "RemoteDrivingGains"]


@dataclass(frozen=True)
class GainPoint:
    """PID gains at one value of the scheduling variable v_ref [m/s]."""

    reference_speed_mps: float
    kp_n_per_mps: float
    ki_n_per_m: float
    kd_n_s_per_mps: float = 0.0


DEFAULT_GAIN_TABLE: tuple[GainPoint, ...] = (
    # Tuned on the URV point-mass model: stiffer at low speed, where resistance gives little
    # damping and stopping precision matters; softer at speed, where the power limit binds.
    GainPoint(0.0, 14_000.0, 2_000.0),
    GainPoint(10.0, 12_000.0, 1_500.0),
    GainPoint(30.0, 9_000.0, 1_000.0),
    GainPoint(60.0, 7_000.0, 700.0),
)


@dataclass(frozen=True, kw_only=True)
class RemoteDrivingGains:
    table: tuple[GainPoint, ...] = DEFAULT_GAIN_TABLE
    reference_acceleration_mps2: float = 0.5
    reference_deceleration_mps2: float = 0.6
    integration_band_mps: float = 0.5
    """The integral acts only while the speed is within this band of the reference: the lag
    behind a ramp the vehicle cannot follow (power-limited) is not stored, to be paid back as
    an overshoot of the target."""

    def at(self, reference_speed_mps: float) -> tuple[float, float, float]:
        """(k_p, k_i, k_d) at v_ref, interpolated linearly in the table."""
        speeds = [point.reference_speed_mps for point in self.table]
        index = bisect.bisect_right(speeds, reference_speed_mps)
        if index == 0:
            point = self.table[0]
            return point.kp_n_per_mps, point.ki_n_per_m, point.kd_n_s_per_mps
        if index == len(self.table):
            point = self.table[-1]
            return point.kp_n_per_mps, point.ki_n_per_m, point.kd_n_s_per_mps
        low, high = self.table[index - 1], self.table[index]
        share = (reference_speed_mps - low.reference_speed_mps) / (
            high.reference_speed_mps - low.reference_speed_mps
        )
        return (
            low.kp_n_per_mps + share * (high.kp_n_per_mps - low.kp_n_per_mps),
            low.ki_n_per_m + share * (high.ki_n_per_m - low.ki_n_per_m),
            low.kd_n_s_per_mps + share * (high.kd_n_s_per_mps - low.kd_n_s_per_mps),
        )


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

    def feedforward_n(self, gradient_permille: float) -> float:
        """M g sin ᾱ + M f_v cos ᾱ [N] for a gradient [‰]."""
        slope = math.atan(gradient_permille / 1000.0)
        return (
            self.mass_kg
            * GRAVITY_MPS2
            * (math.sin(slope) + self.rolling_coefficient * math.cos(slope))
        )

    def align(self, force_n: float, *, speed_mps: float, gradient_permille: float) -> None:
        """Take over at ``force_n``: reference at the current speed, integral set so that the
        next output, with no error, is that force (bumpless transfer)."""
        self.reset(speed_mps)
        _, ki, _ = self.gains.at(speed_mps)
        if ki > 0:
            self._integral = (force_n - self.feedforward_n(gradient_permille)) / ki

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
        kp, ki, kd = g.at(self.reference_speed_mps)

        error = self.reference_speed_mps - speed_mps
        derivative = 0.0 if self._previous_error is None else (error - self._previous_error) / dt_s
        self._previous_error = error
        candidate_integral = self._integral + error * dt_s
        demand = (
            kp * error
            + ki * candidate_integral
            + kd * derivative
            + self.feedforward_n(gradient_permille)
        )
        low, high = force_limits_n
        if low < demand < high and abs(error) <= g.integration_band_mps:
            self._integral = candidate_integral
        if target_speed_mps == 0.0 and self.reference_speed_mps == 0.0 and speed_mps < 0.05:
            self._integral = 0.0
            return low  # hold the stopped vehicle with the brake
        return min(max(demand, low), high)
