"""The Energy Manager of seed 000 (its fig. 5, the ATO-OB logical architecture): the energy to
finish the mission against what the batteries and the range extender (RE) hold.

From the journey's plan (the ODP) and the vehicle model it works out the energy still needed
to finish the journey (the mission: one journey profile); from the battery management systems'
state of charge (SOC), as the VCU reads it over its bus (:class:`PowertrainReading`, never the
plant's state), and the vehicle's data, the energy the batteries and the RE can still give:

- traction: the plan's reference run backwards through the point-mass model, the positive part
  of force × distance at the wheel, over the drives' efficiency η_d to the DC bus; braking is
  not credited (regeneration stops below 10 km/h and fades at high SOC: the conservative side);
- auxiliaries: their constant load × the plan's time still to run;
- batteries: (SOC − floor) × the packs' nominal energy × the cells' efficiency, the floor being
  the VCU's charge-sustaining threshold: below it the VCU phases the batteries' discharge out and
  keeps the rest as a reserve for a failed RE (``docs/vcu.md``);
- RE: its rated power over the time still to run, at most what the fuel on board gives at the
  engine's best specific consumption (the VCU runs it at full power while sustaining charge).

The margin is available − needed [J]; it is *short* when below :attr:`EnergyManagerParameters.
reserve_share` of the energy needed (model mismatch and tracking drew 8.7 % more than the plan
on the ring lap, issue 22). Abbreviations as in ``onboard.adf``: ODP, RE, SOC.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from onboard.adf.energy import track_force_n
from onboard.adf.odp import OdpPlan
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS
from onboard.plant.point_mass import PointMassParameters
from onboard.plant.powertrain import PowertrainParameters
from onboard.plant.readings import PowertrainReading
from onboard.vcu.parameters import VcuParameters, vcu_parameters_for
from protocol.units import J_PER_KWH

__all__ = [
    "EnergyAssessment",
    "EnergyManager",
    "EnergyManagerParameters",
    "PlanEnergy",
    "plan_energy",
]

FloatArray = npt.NDArray[np.float64]
SECONDS_PER_HOUR = 3600.0
KG_PER_J_PER_G_PER_KWH = 1.0e-3 / J_PER_KWH
"""A specific consumption in g/kWh times this is kg/J."""
SAMPLE_S = 0.5
"""The plan's reference is sampled at this step [s] for its energy."""
RESERVE_SHARE = 0.10
"""The energy the margin must keep on top of the need, as a share of the need."""


@dataclass(frozen=True, kw_only=True)
class EnergyManagerParameters:
    """The vehicle's data the Energy Manager reckons with (SI units, shares in [0, 1])."""

    battery_energy_j: float
    """The packs' nominal energy, all of them, from SOC 0 to 1 [J]."""
    battery_efficiency: float
    soc_floor: float
    """The SOC below which the batteries no longer feed traction (the VCU's sustaining one)."""
    drive_efficiency: float
    auxiliary_power_w: float
    range_extender_power_w: float
    """The RE's rated electrical power [W] (0: no RE, or out of service)."""
    range_extender_fuel_kg: float | None = None
    """The fuel on board at power-up [kg]; None when not monitored (the RE's power alone
    bounds it)."""
    range_extender_kg_per_j: float = 235.0 * KG_PER_J_PER_G_PER_KWH
    """The engine's best specific consumption [kg/J] (235 g/kWh, ``docs/vcu.md``)."""
    reserve_share: float = RESERVE_SHARE

    @classmethod
    def for_urv(cls) -> EnergyManagerParameters:
        """The URV's: its bogie's VCU and the seed 003 powertrain."""
        return cls.for_vehicle(vcu_parameters_for(URV_BOGIE_PARAMETERS), PowertrainParameters())

    @classmethod
    def for_vehicle(
        cls,
        vcu: VcuParameters,
        powertrain: PowertrainParameters,
        *,
        range_extender_fuel_kg: float | None = None,
    ) -> EnergyManagerParameters:
        """From the VCU's and the powertrain's data: what the vehicle is built as."""
        battery = powertrain.battery
        consumption = min(c for c in powertrain.range_extender.specific_consumption_g_per_kwh if c)
        return cls(
            battery_energy_j=powertrain.pack_count
            * battery.nominal_voltage_v
            * battery.capacity_ah
            * SECONDS_PER_HOUR,
            battery_efficiency=battery.efficiency,
            soc_floor=vcu.sustaining_soc_on,
            drive_efficiency=vcu.drive_efficiency,
            auxiliary_power_w=vcu.auxiliary_power_w,
            range_extender_power_w=vcu.range_extender_max_power_w,
            range_extender_fuel_kg=range_extender_fuel_kg,
            range_extender_kg_per_j=consumption * KG_PER_J_PER_G_PER_KWH,
        )


@dataclass(frozen=True)
class PlanEnergy:
    """A plan's traction energy at the wheel, cumulated over its time."""

    times_s: FloatArray
    """Sample times [s], the plan's (from the journey's start), increasing."""
    wheel_j: FloatArray
    """Traction energy at the wheel from the plan's start to each sample [J]."""

    @property
    def end_s(self) -> float:
        return float(self.times_s[-1])

    @property
    def total_j(self) -> float:
        return float(self.wheel_j[-1])

    def to_go_j(self, journey_s: float) -> float:
        """Traction energy at the wheel [J] from ``journey_s`` [s] to the plan's end."""
        done = float(np.interp(journey_s, self.times_s, self.wheel_j))
        return max(self.total_j - done, 0.0)


def plan_energy(
    plan: OdpPlan, model: PointMassParameters, *, step_s: float = SAMPLE_S
) -> PlanEnergy:
    """The traction energy at the wheel that following ``plan`` exactly takes, cumulated.

    Force = M(1 + ρ) dv/dt + Davis(v) + gradient and curve forces; energy = Σ max(F, 0) Δs.
    """
    count = max(int(math.ceil(plan.end_s / step_s)) + 1, 2)
    times = np.linspace(0.0, plan.end_s, count)
    samples = np.array([plan.reference(float(t)) for t in times])
    distances, speeds = samples[:, 0], samples[:, 1]
    mass = model.mass_kg * (1.0 + model.rotating_mass_factor)
    ds = np.diff(distances)
    v = 0.5 * (speeds[1:] + speeds[:-1])
    acceleration = np.diff(speeds) / np.diff(times)
    resistance = model.davis_a_n + model.davis_b_n_per_mps * v + model.davis_c_n_per_mps2 * v**2
    middles = 0.5 * (distances[1:] + distances[:-1])
    track = np.array([track_force_n(plan.track_map, model, plan.chainage_m(d)) for d in middles])
    force = mass * acceleration + resistance + track
    work = np.where(ds > 0.0, np.maximum(force, 0.0) * np.maximum(ds, 0.0), 0.0)
    return PlanEnergy(times, np.concatenate(([0.0], np.cumsum(work))))


@dataclass(frozen=True)
class EnergyAssessment:
    """The Energy Manager's reckoning at one instant [J, shares in [0, 1]]."""

    soc: float | None
    """The BMS's SOC as last read (None: no battery reading, e.g. the point-mass vehicle)."""
    energy_to_go_j: float | None
    """Electrical energy at the DC bus to finish the journey: traction and auxiliaries."""
    traction_to_go_j: float | None
    """Its traction part, at the bus."""
    battery_available_j: float | None
    range_extender_available_j: float | None
    margin_j: float | None
    """Available − needed; None without a journey or a SOC."""
    range_extender_share: float | None
    """The share of the energy to go the RE gives at most (it runs first, the batteries
    cover the rest)."""
    short: bool
    """The margin is below the reserve (:attr:`EnergyManagerParameters.reserve_share`)."""


class EnergyManager:
    """Battery, fuel and traction status → the energy to complete the mission (seed 000)."""

    def __init__(self, parameters: EnergyManagerParameters, model: PointMassParameters) -> None:
        self.parameters = parameters
        self.model = model
        self.soc: float | None = None
        self.fuel_used_kg = 0.0
        """The fuel the RE has burnt since power-up, from its power reports [kg]."""
        self._last_reading_s: float | None = None
        self._plan: OdpPlan | None = None
        self._energy: PlanEnergy | None = None

    def read(self, reading: PowertrainReading | None) -> None:
        """The BMS's and the RE controller's last report (None: the vehicle has none)."""
        if reading is None:
            return
        if math.isfinite(reading.soc):
            self.soc = min(max(reading.soc, 0.0), 1.0)
        last, self._last_reading_s = self._last_reading_s, reading.time_s
        if last is not None and reading.time_s > last and reading.range_extender_power_w > 0.0:
            energy = reading.range_extender_power_w * (reading.time_s - last)
            self.fuel_used_kg += energy * self.parameters.range_extender_kg_per_j

    def energy_of(self, plan: OdpPlan) -> PlanEnergy:
        """The plan's cumulated traction energy (kept for the plan last asked about)."""
        if plan is not self._plan or self._energy is None:
            self._plan, self._energy = plan, plan_energy(plan, self.model)
        return self._energy

    def assess(self, plan: OdpPlan | None, journey_s: float = 0.0) -> EnergyAssessment:
        """The reckoning with ``plan`` followed from ``journey_s`` [s from the journey's start]
        to its end (None: no journey, the SOC alone)."""
        if plan is None:
            return EnergyAssessment(self.soc, None, None, None, None, None, None, False)
        energy = self.energy_of(plan)
        return assess_energy(
            self.parameters,
            soc=self.soc,
            wheel_to_go_j=energy.to_go_j(journey_s),
            time_to_go_s=max(energy.end_s - journey_s, 0.0),
            fuel_used_kg=self.fuel_used_kg,
        )


def assess_energy(
    parameters: EnergyManagerParameters,
    *,
    soc: float | None,
    wheel_to_go_j: float,
    time_to_go_s: float,
    fuel_used_kg: float = 0.0,
) -> EnergyAssessment:
    """The reckoning from the traction energy at the wheel [J] and the time [s] still to run.

    needed = E_wheel / η_d + P_aux · T; batteries = (SOC − floor)⁺ · E_packs · η_b;
    RE = min(P_RE · T, fuel / c_sp); margin = batteries + RE − needed; short when the margin is
    under ``reserve_share`` × needed.
    """
    p = parameters
    traction = wheel_to_go_j / p.drive_efficiency
    needed = traction + p.auxiliary_power_w * time_to_go_s
    extender = p.range_extender_power_w * time_to_go_s
    if p.range_extender_fuel_kg is not None:
        fuel_left = max(p.range_extender_fuel_kg - fuel_used_kg, 0.0)
        extender = min(extender, fuel_left / p.range_extender_kg_per_j)
    share = min(extender / needed, 1.0) if needed > 0.0 else None
    if soc is None:
        return EnergyAssessment(None, needed, traction, None, extender, None, share, False)
    battery = max(soc - p.soc_floor, 0.0) * p.battery_energy_j * p.battery_efficiency
    margin = battery + extender - needed
    short = margin < p.reserve_share * needed
    return EnergyAssessment(soc, needed, traction, battery, extender, margin, share, short)
