"""Failure and limitation management, seed 003 §3.3, and the range extender's switching.

Each limitation yields either a cap on the traction power drawn from the bus or a factor on
the drives' torque, and names itself in the VCU status:

- low SOC and charge sustaining: the battery's discharge allowance is phased out;
- battery overload: an I²T model of the battery current; above a fraction of its allowance the
  discharge current is held to the continuous rating;
- motor/drive temperature: torque derated linearly between two temperatures;
- slippery rail: after repeated slips within a window, torque held to a fraction for a while.

Energy management switches the range extender (RE) on at low SOC (charge sustaining: full
power) or when the bus load exceeds the battery's planned share or its overload limit, and off
with hysteresis on SOC and on load. While sustaining charge the batteries no longer have a
planned share: their allowance is phased out to a buffer, the packs' continuous rating, which
covers only the load above the RE's output (a grade) with the charge the RE's surplus on the
level and on descents has put back above the threshold: the SOC does not fall below it.
"""

from __future__ import annotations

from collections import deque

from onboard.vcu.parameters import VcuParameters

__all__ = ["BatteryOverload", "EnergyManager", "SlipperyRail", "temperature_factor"]


class BatteryOverload:
    """I²T state [A²·s]: ∫ (I² − I_cont²) dt, never below zero."""

    def __init__(self, parameters: VcuParameters) -> None:
        self.parameters = parameters
        self.accumulated_a2s = 0.0

    def step(self, dt_s: float, current_a: float, continuous_a: float) -> bool:
        """Integrate one step; True while the overload limitation is in force."""
        self.accumulated_a2s += (current_a**2 - continuous_a**2) * dt_s
        self.accumulated_a2s = max(self.accumulated_a2s, 0.0)
        return self.overloaded

    @property
    def fraction(self) -> float:
        return self.accumulated_a2s / self.parameters.i2t_allowance_a2s

    @property
    def overloaded(self) -> bool:
        return self.fraction >= self.parameters.i2t_limit_fraction


def temperature_factor(temperature_c: float, parameters: VcuParameters) -> float:
    """Torque factor [0, 1] for a drive at ``temperature_c`` [°C]."""
    start, limit = parameters.temperature_derating_start_c, parameters.temperature_limit_c
    return min(max((limit - temperature_c) / (limit - start), 0.0), 1.0)


class SlipperyRail:
    """Declares the rail slippery after repeated slips; holds the torque factor for a while."""

    def __init__(self, parameters: VcuParameters) -> None:
        self.parameters = parameters
        self.slip_times_s: deque[float] = deque()
        self.time_s = 0.0
        self.until_s = -1.0

    def step(self, dt_s: float, new_slips: int) -> float:
        """Record ``new_slips`` slip onsets; return the torque factor [0, 1]."""
        p = self.parameters
        self.time_s += dt_s
        self.slip_times_s.extend([self.time_s] * new_slips)
        while self.slip_times_s and self.slip_times_s[0] < self.time_s - p.slippery_rail_window_s:
            self.slip_times_s.popleft()
        if len(self.slip_times_s) >= p.slippery_rail_slip_count:
            self.until_s = self.time_s + p.slippery_rail_hold_s
            self.slip_times_s.clear()
        return p.slippery_rail_torque_fraction if self.active else 1.0

    @property
    def active(self) -> bool:
        return self.time_s < self.until_s


class EnergyManager:
    """Range extender switching and reference, and the battery's discharge allowance [W]."""

    def __init__(self, parameters: VcuParameters) -> None:
        self.parameters = parameters
        self.sustaining = False
        self.range_extender_on = False
        self.battery_allowance_w = float("inf")
        self.phase_out_w = float("inf")
        """The discharge allowance phased out since charge sustaining began [W]."""

    def step(
        self,
        dt_s: float,
        *,
        soc: float,
        bus_load_w: float,
        max_discharge_w: float,
        battery_overloaded: bool = False,
        continuous_discharge_w: float = 0.0,
    ) -> float:
        """Update with the SOC and the bus load [W] (drives + auxiliaries); return RE ref [W].

        An overloaded battery (I²T) calls the RE to full power to relieve it. While sustaining
        charge, the allowance is phased out at ``battery_phase_out_rate_w_per_s`` down to the
        buffer: the packs' continuous power ``continuous_discharge_w`` [W] (1 C), ramped to zero
        as the SOC comes down to the threshold ``sustaining_soc_on``.
        """
        p = self.parameters
        if soc < p.sustaining_soc_on:
            self.sustaining = True
        elif soc > p.sustaining_soc_off:
            self.sustaining = False
        if self.sustaining:
            phased = min(self.phase_out_w, max_discharge_w)
            self.phase_out_w = max(phased - p.battery_phase_out_rate_w_per_s * dt_s, 0.0)
            above = (soc - p.sustaining_soc_on) / p.sustaining_buffer_band
            buffer = min(continuous_discharge_w, max_discharge_w) * min(max(above, 0.0), 1.0)
            self.battery_allowance_w = max(self.phase_out_w, buffer)
        else:
            self.phase_out_w = self.battery_allowance_w = max_discharge_w
        share = min(p.battery_share_w, max_discharge_w)
        excess = bus_load_w - share
        if self.sustaining or battery_overloaded or excess > p.range_extender_on_power_w:
            self.range_extender_on = True
        elif excess < p.range_extender_off_power_w:
            self.range_extender_on = False
        if not self.range_extender_on:
            return 0.0
        if self.sustaining or battery_overloaded:
            return p.range_extender_max_power_w
        return min(max(excess, 0.0), p.range_extender_max_power_w)
