"""The VCU's parameters and the signals it exchanges, seed 003 §3.

Seed 003 describes the strategies but gives few numbers; every value below is either from the
seed (marked so) or an assumption written next to it. ``docs/vcu.md`` lists them together.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from enum import StrEnum

from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS, BogieParameters
from protocol.units import MPS_PER_KMH

__all__ = [
    "vcu_parameters_for",
    "BrakingPhase",
    "Limitation",
    "VcuInputs",
    "VcuParameters",
    "VcuStatus",
]


@dataclass(frozen=True, kw_only=True)
class VcuParameters:
    """Everything the VCU's strategies are tuned with (SI units)."""

    wheel_radius_m: float = 0.46
    """Assumed: 920 mm new high-speed wheels."""
    max_motor_torque_nm: float = 6_900.0
    """Per wheelset: 15 kN at the rail per axle, 30 kN in all (URV_PARAMETERS)."""
    max_motor_power_w: float = 200_000.0
    """Per drive: 400 kW in all (URV_PARAMETERS); torque = min(T_max, P_max / ω)."""
    # Torque split k_d (seed 003 §3.1, fig. 3): the trailing axle alone at standstill, then
    # the leading axle takes a share that grows to one half at ``equal_split_speed_mps``.
    split_start_speed_mps: float = 1.0
    equal_split_speed_mps: float = 8.0
    # Slip protection (seed 003 §3.1).
    slip_speed_threshold_mps: float = 0.5
    slip_relative_threshold: float = 0.05
    """An axle slips when its peripheral speed departs from the fused speed (or from the other
    axle's) by more than max(threshold, relative × speed)."""
    slip_cutoff_s: float = 0.3
    slip_restart_fraction: float = 0.5
    """After a cut-off the axle restarts at this fraction of the torque it had when it slipped."""
    slip_recovery_rate_per_s: float = 0.25
    """The restart limit then rises by this fraction of the maximum torque per second."""
    slippery_rail_slip_count: int = 3
    slippery_rail_window_s: float = 30.0
    slippery_rail_torque_fraction: float = 0.6
    slippery_rail_hold_s: float = 60.0
    # Blended braking (seed 003 §3.2, fig. 4).
    blending_speed_mps: float = 30.0 * MPS_PER_KMH
    """Below it the pneumatic brake joins (phase 2)."""
    min_electric_braking_speed_mps: float = 10.0 * MPS_PER_KMH
    """Below it the pneumatic brake alone acts (phase 3)."""
    brake_gain_nm_per_pa: float = 6.9e-3
    """Per wheelset: 15 kN at the rail for the vehicle = 6900 N·m per axle at 5 bar."""
    max_brake_pressure_pa: float = 5.0e5
    regen_full_soc: float = 0.90
    regen_zero_soc: float = 0.95
    """k_e falls linearly from 1 at ``regen_full_soc`` to 0 at ``regen_zero_soc`` (fig. 4c)."""
    # Limitations (seed 003 §3.3).
    i2t_allowance_a2s: float = (400.0**2 - 210.0**2) * 60.0
    """I²T capacity on the two packs' total current: 60 s at 2 × 200 A over the 2 × 1 C rating."""
    i2t_limit_fraction: float = 0.8
    """Above this fraction of the allowance the discharge current is held to the 1 C rating."""
    temperature_derating_start_c: float = 140.0
    temperature_limit_c: float = 160.0
    """Drive torque falls linearly from full to zero between these temperatures."""
    # Energy management (seed 003 §3.3, §7).
    sustaining_soc_on: float = 0.465
    sustaining_soc_off: float = 0.50
    """Below ``on`` the RE runs at full power and battery discharge is phased out; it stops
    at ``off``. Chosen to keep a reserve for a range-extender failure and tuned so that the
    seed's 50 % mission reaches the threshold after about 21 min (docs/vcu.md)."""
    battery_share_w: float = 15_000.0
    """Outside charge sustaining the battery covers this much of the bus load; the range
    extender covers the rest, so SOC falls slowly (seed 003 §7.1)."""
    range_extender_on_power_w: float = 25_000.0
    range_extender_off_power_w: float = 10_000.0
    """Hysteresis on the load the RE would have to cover before it starts or stops."""
    battery_phase_out_rate_w_per_s: float = 500.0
    """While sustaining, the battery's discharge allowance falls at this rate (seed 003 §7.2)
    to the buffer: the packs' continuous (1 C) power, for the load above the RE's output."""
    sustaining_buffer_band: float = 0.005
    """While sustaining, the buffer falls to zero as the SOC comes down to ``sustaining_soc_on``
    over this band: the batteries lend only the charge the RE has put back above it."""
    range_extender_max_power_w: float = 100_000.0
    auxiliary_power_w: float = 5_000.0
    drive_efficiency: float = 0.92
    # Speed loop: a PI for the optional speed reference, force at the rail [N].
    speed_kp_n_per_mps: float = 8_000.0
    speed_ki_n_per_m: float = 800.0


class BrakingPhase(StrEnum):
    NONE = "none"
    ELECTRIC = "electric"
    BLENDED = "blended"
    PNEUMATIC = "pneumatic"


class Limitation(StrEnum):
    LOW_SOC = "low_soc"
    HIGH_SOC = "high_soc"
    BATTERY_OVERLOAD = "battery_overload"
    POWER = "power"
    TEMPERATURE = "temperature"
    SLIPPERY_RAIL = "slippery_rail"


@dataclass(frozen=True, kw_only=True)
class VcuInputs:
    """What the VCU reads at each step: demand from the ADF, feedback over the CAN buses.

    Speeds are magnitudes along the direction of motion (``direction`` +1 forwards, −1 in
    reverse); wheel speeds are the axles' magnitudes [rad/s]. The force demand [N] is at the
    rail, positive pulling in the direction of motion, negative braking.
    """

    force_demand_n: float = 0.0
    speed_reference_mps: float | None = None
    direction: int = 1
    fused_speed_mps: float = 0.0
    wheel_speed_front_radps: float = 0.0
    wheel_speed_rear_radps: float = 0.0
    soc: float = 1.0
    battery_current_a: float = 0.0
    battery_voltage_v: float = 742.0
    max_discharge_power_w: float = 1.0e9
    max_charge_power_w: float = 1.0e9
    continuous_current_a: float = 210.0
    range_extender_power_w: float = 0.0
    motor_temperature_front_c: float = 25.0
    motor_temperature_rear_c: float = 25.0


@dataclass(frozen=True, slots=True)
class VcuStatus:
    """What the VCU did at its last step, for monitoring and tests."""

    braking_phase: BrakingPhase = BrakingPhase.NONE
    slip_front: bool = False
    slip_rear: bool = False
    limitations: frozenset[Limitation] = frozenset()
    range_extender_on: bool = False
    force_demand_n: float = 0.0
    electric_braking_torque_nm: float = 0.0
    pneumatic_braking_torque_nm: float = 0.0
    traction_power_limit_w: float = 0.0

    @property
    def slip_detected(self) -> bool:
        return self.slip_front or self.slip_rear


def vcu_parameters_for(
    bogie: BogieParameters = URV_BOGIE_PARAMETERS, base: VcuParameters | None = None
) -> VcuParameters:
    """VCU parameters whose plant constants are the bogie's: wheel radius [m], motor torque
    [N·m] and power [W] per wheelset, brake gain [N·m/Pa] and maximum pressure [Pa].

    The VCU's defaults assume 6.9e-3 N·m/Pa up to 5 bar; the bogie's brakes give 1.035e-2 N·m/Pa
    up to 4 bar, so without this the VCU's pressures would brake half as hard again as meant.
    """
    return dataclasses.replace(
        base if base is not None else VcuParameters(),
        wheel_radius_m=bogie.wheel_radius_m,
        max_motor_torque_nm=bogie.motor_max_torque_nm,
        max_motor_power_w=bogie.motor_max_power_w,
        brake_gain_nm_per_pa=bogie.brake_gain_m3,
        max_brake_pressure_pa=bogie.brake_max_pressure_pa,
    )
