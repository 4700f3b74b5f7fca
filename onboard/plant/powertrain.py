"""The series-hybrid powertrain of seed 003 §6: battery packs, drives, range extender, auxiliaries.

Static models, as in the seed, except the range extender's first-order lag and a first-order
thermal model of each traction drive (the VCU's temperature limitation needs a temperature).
The DC bus balances at every step (seed 003 eq. 39, with the auxiliaries' load added):

    P_batteries + P_RE = P_drives + P_auxiliaries

where P_drives is the drives' electrical power (negative while braking electrically). Sign
convention: battery power and current are positive when discharging. Everything is SI; the
state of charge (SOC) is a fraction in [0, 1]. This is the plant's truth: it does not clamp
what the VCU asks; the battery management system (BMS) limits are published for the VCU
through :meth:`Powertrain.bms_status`, and exceeding them is recorded, not prevented.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

__all__ = [
    "BatteryParameters",
    "BmsStatus",
    "DriveParameters",
    "DriveThermalModel",
    "Powertrain",
    "PowertrainParameters",
    "PowertrainState",
    "RangeExtender",
    "RangeExtenderParameters",
    "BatteryPack",
]

SECONDS_PER_HOUR = 3600.0


@dataclass(frozen=True, kw_only=True)
class BatteryParameters:
    """One LiFePO4 pack; seed 003 §6.1 unless marked as assumed."""

    nominal_voltage_v: float = 742.0
    capacity_ah: float = 105.0
    max_discharge_current_a: float = 200.0
    max_charge_current_a: float = 200.0
    """Assumed equal to the seed's 200 A maximum current."""
    efficiency: float = 0.95
    open_circuit_voltage_span: float = 0.06
    """Assumed: the open-circuit voltage goes linearly from (1 − span/2) to (1 + span/2) times
    the nominal voltage between SOC 0 and 1 (LiFePO4 is flat over most of its range)."""
    continuous_current_a: float = 105.0
    """Assumed 1 C: the current the I²T overload model lets pass indefinitely."""
    min_soc: float = 0.10
    max_soc: float = 0.95
    """Assumed BMS window: no discharge below ``min_soc``, no charge above ``max_soc``."""
    derating_soc_band: float = 0.05
    """Assumed: the BMS limits ramp to zero over this SOC band at each end of the window."""


@dataclass(frozen=True, kw_only=True)
class RangeExtenderParameters:
    """Diesel engine and generator, seed 003 §6.2; the working points are assumed."""

    working_points_w: tuple[float, ...] = (0.0, 25_000.0, 50_000.0, 75_000.0, 100_000.0)
    """Electrical power of the working points on the engine map (seed 003 fig. 11 gives their
    principle, not the numbers). The last one is the maximum power; a reference between two
    is reached by interpolating the engine speed and torque, so the power is continuous."""
    specific_consumption_g_per_kwh: tuple[float, ...] = (0.0, 290.0, 250.0, 235.0, 240.0)
    """Assumed brake-specific fuel consumption at each working point, electrical kWh (small
    diesels: 230–290 g/kWh, best near three quarters of full load)."""
    time_constant_s: float = 3.0
    """Assumed lag of engine and generator (seed 003 eq. 37 gives the form, not τ_RE)."""


@dataclass(frozen=True, kw_only=True)
class DriveParameters:
    """Traction drive (inverter, motor and gearbox) efficiency and thermal model, assumed."""

    efficiency: float = 0.92
    """Inverter 0.97 × motor 0.95, the same motoring and generating."""
    ambient_temperature_c: float = 25.0
    continuous_torque_nm: float = 4_000.0
    """Wheelset torque the drive carries forever at ``rated_temperature_rise_k``."""
    rated_temperature_rise_k: float = 100.0
    thermal_time_constant_s: float = 900.0
    """First-order winding and inverter heating: rise ∝ torque² (copper losses dominate)."""


@dataclass(frozen=True, kw_only=True)
class PowertrainParameters:
    battery: BatteryParameters = BatteryParameters()
    pack_count: int = 2
    range_extender: RangeExtenderParameters = RangeExtenderParameters()
    drive: DriveParameters = DriveParameters()
    auxiliary_power_w: float = 5_000.0
    """Assumed constant: inspection instrumentation, computers, compressor and cooling fed
    through the two DC/DC converters of seed 003 fig. 10."""


@dataclass(frozen=True, slots=True)
class BmsStatus:
    """What the battery management systems report to the VCU (both packs together)."""

    soc: float
    voltage_v: float
    current_a: float
    max_discharge_power_w: float
    max_charge_power_w: float
    max_discharge_current_a: float
    continuous_current_a: float


@dataclass(frozen=True, slots=True)
class PowertrainState:
    """One step's powers [W] and the accumulated energies [J] and fuel [kg]."""

    soc: float
    battery_power_w: float
    battery_current_a: float
    drives_power_w: float
    range_extender_power_w: float
    auxiliary_power_w: float
    battery_energy_out_j: float
    battery_energy_in_j: float
    range_extender_energy_j: float
    fuel_kg: float
    motor_temperature_front_c: float
    motor_temperature_rear_c: float


def _ramp(value: float, zero_at: float, full_at: float) -> float:
    """Linear 0 → 1 from ``zero_at`` to ``full_at`` (either order), clipped."""
    if zero_at == full_at:
        return 1.0 if value >= full_at else 0.0
    return min(max((value - zero_at) / (full_at - zero_at), 0.0), 1.0)


class BatteryPack:
    """One pack: 95 % efficiency on the terminal power, Coulomb-counting SOC (seed 003 eq. 36)."""

    def __init__(self, parameters: BatteryParameters, *, soc: float = 1.0) -> None:
        if not 0.0 <= soc <= 1.0:
            raise ValueError("the SOC is a fraction in [0, 1]")
        self.parameters = parameters
        self.soc = soc
        self.current_a = 0.0
        self.energy_out_j = 0.0
        self.energy_in_j = 0.0

    def open_circuit_voltage_v(self) -> float:
        p = self.parameters
        return p.nominal_voltage_v * (1.0 + p.open_circuit_voltage_span * (self.soc - 0.5))

    def step(self, dt_s: float, terminal_power_w: float) -> float:
        """Deliver ``terminal_power_w`` [W] (negative: charge) for ``dt_s`` [s]; return [A].

        The cells supply P/η when discharging and take η·P when charging; the current is that
        internal power over the open-circuit voltage, and SOC falls by I·dt / (3600 · C_n).
        """
        p = self.parameters
        if terminal_power_w >= 0.0:
            internal_w = terminal_power_w / p.efficiency
            self.energy_out_j += terminal_power_w * dt_s
        else:
            internal_w = terminal_power_w * p.efficiency
            self.energy_in_j -= terminal_power_w * dt_s
        self.current_a = internal_w / self.open_circuit_voltage_v()
        self.soc -= self.current_a * dt_s / (p.capacity_ah * SECONDS_PER_HOUR)
        self.soc = min(max(self.soc, 0.0), 1.0)
        return self.current_a

    def max_discharge_current_a(self) -> float:
        """BMS discharge limit [A]: full, ramped to zero over the band above ``min_soc``."""
        p = self.parameters
        band = _ramp(self.soc, p.min_soc, p.min_soc + p.derating_soc_band)
        return p.max_discharge_current_a * band

    def max_charge_current_a(self) -> float:
        """BMS charge limit [A]: full, ramped to zero over the band below ``max_soc``."""
        p = self.parameters
        band = _ramp(self.soc, p.max_soc, p.max_soc - p.derating_soc_band)
        return p.max_charge_current_a * band


class RangeExtender:
    """Power reference clipped to the map, first-order lag (seed 003 eq. 37–38), fuel use."""

    def __init__(self, parameters: RangeExtenderParameters = RangeExtenderParameters()) -> None:
        if len(parameters.working_points_w) != len(parameters.specific_consumption_g_per_kwh):
            raise ValueError("one specific consumption per working point")
        self.parameters = parameters
        self.power_w = 0.0
        self.energy_j = 0.0
        self.fuel_kg = 0.0

    @property
    def max_power_w(self) -> float:
        return self.parameters.working_points_w[-1]

    def specific_consumption_g_per_kwh(self, power_w: float) -> float:
        """Specific consumption [g/kWh] interpolated between working points."""
        points = self.parameters.working_points_w
        values = self.parameters.specific_consumption_g_per_kwh
        index = min(max(bisect.bisect_right(points, power_w), 1), len(points) - 1)
        low, high = points[index - 1], points[index]
        weight = _ramp(power_w, low, high)
        return values[index - 1] + weight * (values[index] - values[index - 1])

    def step(self, dt_s: float, reference_w: float) -> float:
        """Advance by ``dt_s`` [s] towards ``reference_w`` [W] within [0, max]; return [W]."""
        target = min(max(reference_w, 0.0), self.max_power_w)
        blend = min(dt_s / self.parameters.time_constant_s, 1.0)
        self.power_w += (target - self.power_w) * blend
        self.energy_j += self.power_w * dt_s
        grams = self.specific_consumption_g_per_kwh(self.power_w) * self.power_w * dt_s
        self.fuel_kg += grams / (1000.0 * SECONDS_PER_HOUR * 1000.0)
        return self.power_w


class DriveThermalModel:
    """First-order temperature [°C] of one drive: τ dT/dt = T_amb + ΔT_rated (T/T_cont)² − T."""

    def __init__(self, parameters: DriveParameters = DriveParameters()) -> None:
        self.parameters = parameters
        self.temperature_c = parameters.ambient_temperature_c

    def step(self, dt_s: float, torque_nm: float) -> float:
        p = self.parameters
        rise = p.rated_temperature_rise_k * (torque_nm / p.continuous_torque_nm) ** 2
        blend = min(dt_s / p.thermal_time_constant_s, 1.0)
        self.temperature_c += (p.ambient_temperature_c + rise - self.temperature_c) * blend
        return self.temperature_c


class Powertrain:
    """Packs in parallel on one DC bus, two drives, range extender, auxiliaries."""

    def __init__(
        self, parameters: PowertrainParameters = PowertrainParameters(), *, soc: float = 1.0
    ) -> None:
        self.parameters = parameters
        self.packs = [
            BatteryPack(parameters.battery, soc=soc) for _ in range(parameters.pack_count)
        ]
        self.range_extender = RangeExtender(parameters.range_extender)
        self.thermal_front = DriveThermalModel(parameters.drive)
        self.thermal_rear = DriveThermalModel(parameters.drive)
        self.state = self._state(0.0, 0.0, 0.0)

    @property
    def soc(self) -> float:
        return sum(pack.soc for pack in self.packs) / len(self.packs)

    def drive_electrical_power_w(self, mechanical_power_w: float) -> float:
        """Electrical power [W] of a drive delivering ``mechanical_power_w`` at the wheelset."""
        efficiency = self.parameters.drive.efficiency
        if mechanical_power_w >= 0.0:
            return mechanical_power_w / efficiency
        return mechanical_power_w * efficiency

    def bms_status(self) -> BmsStatus:
        """The BMS limits for the VCU, summed over the packs (powers at the terminals)."""
        voltage = sum(p.open_circuit_voltage_v() for p in self.packs) / len(self.packs)
        discharge_a = sum(p.max_discharge_current_a() for p in self.packs)
        charge_a = sum(p.max_charge_current_a() for p in self.packs)
        efficiency = self.parameters.battery.efficiency
        return BmsStatus(
            soc=self.soc,
            voltage_v=voltage,
            current_a=sum(p.current_a for p in self.packs),
            max_discharge_power_w=discharge_a * voltage * efficiency,
            max_charge_power_w=charge_a * voltage / efficiency,
            max_discharge_current_a=discharge_a,
            continuous_current_a=self.parameters.battery.continuous_current_a * len(self.packs),
        )

    def step(
        self,
        dt_s: float,
        *,
        mechanical_power_front_w: float,
        mechanical_power_rear_w: float,
        range_extender_reference_w: float,
        motor_torque_front_nm: float = 0.0,
        motor_torque_rear_nm: float = 0.0,
    ) -> PowertrainState:
        """Advance by ``dt_s`` [s] with the drives' mechanical powers at the wheelsets [W]."""
        drives = self.drive_electrical_power_w(mechanical_power_front_w)
        drives += self.drive_electrical_power_w(mechanical_power_rear_w)
        range_extender = self.range_extender.step(dt_s, range_extender_reference_w)
        battery = drives + self.parameters.auxiliary_power_w - range_extender
        for pack in self.packs:
            pack.step(dt_s, battery / len(self.packs))
        self.thermal_front.step(dt_s, motor_torque_front_nm)
        self.thermal_rear.step(dt_s, motor_torque_rear_nm)
        self.state = self._state(battery, drives, range_extender)
        return self.state

    def _state(self, battery_w: float, drives_w: float, range_extender_w: float) -> PowertrainState:
        return PowertrainState(
            soc=self.soc,
            battery_power_w=battery_w,
            battery_current_a=sum(p.current_a for p in self.packs),
            drives_power_w=drives_w,
            range_extender_power_w=range_extender_w,
            auxiliary_power_w=self.parameters.auxiliary_power_w,
            battery_energy_out_j=sum(p.energy_out_j for p in self.packs),
            battery_energy_in_j=sum(p.energy_in_j for p in self.packs),
            range_extender_energy_j=self.range_extender.energy_j,
            fuel_kg=self.range_extender.fuel_kg,
            motor_temperature_front_c=self.thermal_front.temperature_c,
            motor_temperature_rear_c=self.thermal_rear.temperature_c,
        )
