"""The energy certificate of a run: the traction energy driven against the best possible.

After a whole-stack run, each leg the train drove (from the standstill it left to the stop it
served) is timed and measured on the plant's truth: its departure (the last telemetry sample at
rest before it moved), its arrival (the stop's record), the distance run between them and the
traction energy at the wheel the plant counted. Three energies are set side by side per leg:

- **driven**: the plant's traction energy over the leg (the truth);
- **plan**: the energy of the reference the ADF followed over the leg (the journey's plan, or
  the leg as replanned: the telemetry's reference speed, which is the plan in force at each
  sample), evaluated with the onboard's model (what the plan promised);
- **optimum**: the offline optimum (:func:`onboard.adf.energy.optimal_leg`, IPOPT collocation)
  for the same leg in the same time, from the actual departure to the actual arrival, computed
  with the plant's true parameters and under the same limits as the plans.

The ratios driven/optimum and plan/optimum are those of the sums over the legs; a leg whose
optimum could not be solved leaves them null (docs/scenarios.md, "The energy certificate").
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from deploy.scenario.kpi_model import EnergyCertificate, LegEnergy
from deploy.scenario.run_context import RunContext
from onboard.adf.energy import OptimalLeg, optimal_leg, track_force_n
from onboard.plant import URV_PARAMETERS
from onboard.plant.point_mass import PointMassModel, PointMassParameters
from protocol.units import J_PER_KWH
from trackdb import TrackMap

__all__ = [
    "MAX_OPTIMUM_NODES",
    "JourneyTiming",
    "LegRun",
    "OptimumProfile",
    "RunEnergy",
    "certify",
    "run_energy",
    "driven_legs",
    "reference_energy_j",
    "true_parameters",
]

FloatArray = npt.NDArray[np.float64]
STANDSTILL_MPS = 0.01
"""The telemetry's standstill, as the recorder's."""
MIN_LEG_M = 1.0
"""A leg shorter than this [m] is no leg (an EoA close-up, a creep at a stop)."""
OPTIMUM_STEP_M = 10.0
MAX_OPTIMUM_NODES = 1500
"""The collocation's grid: every 10 m, coarser on legs longer than 15 km (the solve time grows
with the nodes; 1500 nodes solve in a few seconds)."""


@dataclass(frozen=True)
class JourneyTiming:
    """Where and when the journey started, and the stops served (journey times of arrival)."""

    origin_s: float
    origin_m: float
    stops: Sequence[tuple[str, float]]
    """(timing point, arrival [s from the journey's start]) in the order served."""


@dataclass(frozen=True)
class LegRun:
    """One leg as the train drove it (plant's truth)."""

    name: str
    departure_s: float
    arrival_s: float
    start_m: float
    distance_m: float
    driven_j: float
    plan_start_s: float
    """From when the leg's reference is read: the previous arrival, or the journey's start."""


@dataclass(frozen=True)
class OptimumProfile:
    """A leg's optimal speed per distance, for the report."""

    name: str
    distances_m: FloatArray
    speeds_mps: FloatArray


def driven_legs(columns: Mapping[str, np.ndarray], timing: JourneyTiming) -> list[LegRun]:
    """The legs of the journey as driven: from the standstill the train left to each stop."""
    times, speeds = columns["time_s"], columns["speed_mps"]
    positions, energy = columns["position_m"], columns["traction_energy_j"]
    legs: list[LegRun] = []
    since_s = timing.origin_s
    for name, journey_arrival_s in timing.stops:
        arrival_s = timing.origin_s + journey_arrival_s
        window = np.nonzero((times >= since_s) & (times <= arrival_s))[0]
        moving = window[speeds[window] > STANDSTILL_MPS]
        if moving.size:
            first = int(moving[0])
            departure_s = float(times[max(first - 1, int(window[0]))])
            start_m = float(np.interp(departure_s, times, positions))
            distance = float(np.interp(arrival_s, times, positions)) - start_m
            if distance >= MIN_LEG_M and arrival_s > departure_s:
                driven = float(np.interp(arrival_s, times, energy)) - float(
                    np.interp(departure_s, times, energy)
                )
                legs.append(
                    LegRun(name, departure_s, arrival_s, start_m, distance, driven, since_s)
                )
        since_s = arrival_s
    return legs


def reference_energy_j(
    columns: Mapping[str, np.ndarray],
    track_map: TrackMap,
    model: PointMassParameters,
    *,
    start_s: float,
    end_s: float,
) -> float:
    """Traction energy at the wheel [J] that following the recorded reference speed from
    ``start_s`` to ``end_s`` exactly would take on ``model``: M(1 + ρ) dv/dt + resistance +
    track forces (at the true position, within a metre of the reference's), its positive part
    times the distance. Samples without a reference (not in AD) count as at rest."""
    times = columns["time_s"]
    inside = (times >= start_s) & (times <= end_s)
    t = times[inside]
    v = np.nan_to_num(columns["reference_speed_mps"][inside], nan=0.0).clip(min=0.0)
    x = columns["position_m"][inside]
    if t.size < 2:
        return 0.0
    dt, v_mid = np.diff(t), 0.5 * (v[1:] + v[:-1])
    mass = model.mass_kg * (1.0 + model.rotating_mass_factor)
    resistance = (
        model.davis_a_n + model.davis_b_n_per_mps * v_mid + model.davis_c_n_per_mps2 * v_mid**2
    )
    chainages = [track_map.normalise(float(p)) for p in 0.5 * (x[1:] + x[:-1])]
    track = np.array([track_force_n(track_map, model, c) for c in chainages])
    force = mass * np.diff(v) / dt + resistance + track
    moving = v_mid > 0.0
    return float(np.sum(np.maximum(force, 0.0)[moving] * v_mid[moving] * dt[moving]))


def _optimum(
    track_map: TrackMap, truth: PointMassParameters, leg: LegRun, cap_mps: float | None
) -> OptimalLeg | None:
    """The leg's offline optimum on the truth, or None when IPOPT finds none."""
    step = max(OPTIMUM_STEP_M, leg.distance_m / MAX_OPTIMUM_NODES)
    try:
        return optimal_leg(
            track_map,
            truth,
            start_chainage_m=track_map.normalise(leg.start_m),
            distance_m=leg.distance_m,
            duration_s=leg.arrival_s - leg.departure_s,
            cap_mps=cap_mps,
            step_m=step,
        )
    except RuntimeError:  # casadi: the solver failed (an infeasible time under the limits)
        return None


def _ratio(numerator: float, denominator: float | None) -> float | None:
    if denominator is None or denominator <= 0.0:
        return None
    return numerator / denominator


def certify(
    columns: Mapping[str, np.ndarray],
    timing: JourneyTiming,
    *,
    track_map: TrackMap,
    model: PointMassParameters,
    truth: PointMassParameters,
    cap_mps: float | None,
    regenerated_j: float | None,
) -> tuple[EnergyCertificate, list[OptimumProfile]]:
    """The run's certificate and each leg's optimal profile; ``model`` is the onboard's (the
    plan's energy), ``truth`` the plant's (the optimum's)."""
    entries: list[LegEnergy] = []
    profiles: list[OptimumProfile] = []
    for leg in driven_legs(columns, timing):
        plan_j = reference_energy_j(
            columns, track_map, model, start_s=leg.plan_start_s, end_s=leg.arrival_s
        )
        optimum = _optimum(track_map, truth, leg, cap_mps)
        optimum_j = None if optimum is None else optimum.traction_energy_j
        if optimum is not None:
            profiles.append(OptimumProfile(leg.name, optimum.distances_m, optimum.speeds_mps))
        entries.append(
            LegEnergy(
                stop=leg.name,
                departure_s=leg.departure_s,
                arrival_s=leg.arrival_s,
                distance_m=leg.distance_m,
                driven_kwh=leg.driven_j / J_PER_KWH,
                plan_kwh=plan_j / J_PER_KWH,
                optimum_kwh=None if optimum_j is None else optimum_j / J_PER_KWH,
                driven_vs_optimum=_ratio(leg.driven_j, optimum_j),
            )
        )
    return _totals(entries, regenerated_j), profiles


def _totals(legs: list[LegEnergy], regenerated_j: float | None) -> EnergyCertificate:
    driven = math.fsum(leg.driven_kwh for leg in legs)
    plan = math.fsum(leg.plan_kwh for leg in legs)
    optima = [leg.optimum_kwh for leg in legs]
    optimum = None if not legs or None in optima else math.fsum(o or 0.0 for o in optima)
    return EnergyCertificate(
        driven_kwh=driven,
        regenerated_kwh=None if regenerated_j is None else regenerated_j / J_PER_KWH,
        plan_kwh=plan,
        optimum_kwh=optimum,
        driven_vs_optimum=_ratio(driven, optimum),
        plan_vs_optimum=_ratio(plan, optimum),
        legs=legs,
    )


@dataclass(frozen=True)
class RunEnergy:
    """What a run adds to ``kpis.json`` and its report about energy."""

    certificate: EnergyCertificate | None = None
    fallbacks: int | None = None
    profiles: tuple[OptimumProfile, ...] = ()


def true_parameters(dynamics: object) -> PointMassParameters:
    """The plant's true point-mass parameters: the point mass's own; the bogie's, which are
    chosen to agree with :data:`~onboard.plant.point_mass.URV_PARAMETERS` (its mass, Davis
    coefficients and traction envelope), those."""
    if isinstance(dynamics, PointMassModel):
        return dynamics.parameters
    return URV_PARAMETERS


def run_energy(ctx: RunContext, columns: Mapping[str, np.ndarray]) -> RunEnergy:
    """The certificate of a finished whole-stack run; empty without a journey driven."""
    node = ctx.node
    driving = node.stack.driving
    journey = driving.journey
    if journey is None or not ctx.recorder.stops:
        return RunEnergy(fallbacks=None if journey is None else journey.legs_kept_plain)
    timing = JourneyTiming(
        origin_s=driving.progress.origin_s,
        origin_m=driving.progress.origin_m,
        stops=[(stop.name, stop.arrival_s) for stop in ctx.recorder.stops],
    )
    dynamics = node.plant.dynamics
    regenerated = None if isinstance(dynamics, PointMassModel) else node.plant.regen_energy_j
    certificate, profiles = certify(
        columns,
        timing,
        track_map=node.track_map,
        model=node.stack.model,
        truth=true_parameters(dynamics),
        cap_mps=journey.plan.cap_mps,
        regenerated_j=regenerated,
    )
    return RunEnergy(certificate, journey.legs_kept_plain, tuple(profiles))
