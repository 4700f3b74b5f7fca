"""Traction energy of a speed profile, and the offline energy-optimal reference for a leg.

``plan_traction_energy_j`` runs a plan's reference through the point-mass model backwards: the
force a profile needs is M(1 + ρ) dv/dt + resistance + track forces, and the traction energy is
the positive part of force × distance. ``optimal_leg`` is the best any planner could do for a leg
(the reference (b) of the ADF issue): direct collocation over distance with casadi and IPOPT on
the same model, limits and arrival time, minimising traction energy at the wheel:

    min Σ f_i Δs   s.t.  M(1 + ρ)(v_{i+1}² − v_i²)/2 = (f_i − b_i − R(v̄_i) − F_track,i) Δs,
                         Σ 2Δs / (v_i + v_{i+1}) = T,  v_i ≤ min(MRSP, cap),
                         (the same sum up to each passing point = its time),
                         0 ≤ f_i ≤ F_max,  f_i v̄_i ≤ P_max,  0 ≤ b_i,
                         |dv/dt| ≤ a_max,  v_0 = v_K = 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import numpy.typing as npt

from onboard.adf.odp import MAX_ACCELERATION_MPS2, OdpPlan
from onboard.plant.point_mass import CURVE_COEFFICIENT_M, PointMassParameters
from protocol.units import GRAVITY_MPS2
from trackdb import TrackMap

__all__ = ["OptimalLeg", "optimal_leg", "plan_traction_energy_j", "track_force_n"]

FloatArray = npt.NDArray[np.float64]
MIN_AVERAGE_SPEED_MPS = 0.05


def track_force_n(track_map: TrackMap, model: PointMassParameters, chainage_m: float) -> float:
    """Gradient and curve forces [N] on the vehicle at a chainage."""
    weight = model.mass_kg * GRAVITY_MPS2
    grade = weight * math.sin(math.atan(track_map.gradient_permille(chainage_m) / 1000.0))
    radius = track_map.curve_radius_m(chainage_m)
    curve = 0.0 if math.isinf(radius) else weight * CURVE_COEFFICIENT_M / radius / 1000.0
    return grade + curve


def plan_traction_energy_j(
    plan: OdpPlan, model: PointMassParameters, *, step_s: float = 0.1
) -> float:
    """Traction energy at the wheel [J] that following the plan exactly would take."""
    mass = model.mass_kg * (1.0 + model.rotating_mass_factor)
    times = np.arange(0.0, plan.end_s + step_s, step_s)
    samples = np.array([plan.reference(float(t)) for t in times])
    distances, speeds = samples[:, 0], samples[:, 1]
    energy = 0.0
    for i in range(len(times) - 1):
        ds = distances[i + 1] - distances[i]
        if ds <= 0.0:
            continue
        v = 0.5 * (speeds[i] + speeds[i + 1])
        acceleration = (speeds[i + 1] - speeds[i]) / step_s
        resistance = model.davis_a_n + model.davis_b_n_per_mps * v + model.davis_c_n_per_mps2 * v**2
        chainage = plan.chainage_m(0.5 * (distances[i] + distances[i + 1]))
        force = mass * acceleration + resistance + track_force_n(plan.track_map, model, chainage)
        energy += max(force, 0.0) * ds
    return energy


@dataclass(frozen=True)
class OptimalLeg:
    distances_m: FloatArray
    speeds_mps: FloatArray
    traction_forces_n: FloatArray
    brake_forces_n: FloatArray
    traction_energy_j: float
    duration_s: float


def optimal_leg(
    track_map: TrackMap,
    model: PointMassParameters,
    *,
    start_chainage_m: float,
    distance_m: float,
    duration_s: float,
    cap_mps: float | None = None,
    step_m: float = 10.0,
    max_acceleration_mps2: float = MAX_ACCELERATION_MPS2,
    max_deceleration_mps2: float | None = None,
    passing: Sequence[tuple[float, float]] = (),
) -> OptimalLeg:
    """The energy-optimal run of one leg, standstill to standstill, in ``duration_s`` [s].

    ``max_deceleration_mps2`` bounds the total deceleration (brake, resistance and track
    forces together; ``max_acceleration_mps2`` when None), as a plan's kinematic braking rate
    does. ``passing`` are (offset into the leg [m], time from its departure [s]) to pass at
    exactly: each a node of the grid, so the optimum of a leg with passing points is exact."""
    nodes_m = _grid_m(distance_m, step_m, [offset for offset, _ in passing])
    ds_m = np.diff(nodes_m)
    count = len(ds_m)
    nodes = [start_chainage_m + float(x) for x in nodes_m]
    chainages = [start_chainage_m + float(x) for x in 0.5 * (nodes_m[1:] + nodes_m[:-1])]
    ceiling = _ceilings_mps(track_map, model, start_chainage_m, distance_m, cap_mps, nodes)
    track = [track_force_n(track_map, model, c) for c in chainages]

    opti = ca.Opti()
    v = opti.variable(count + 1)
    traction = opti.variable(count)
    brake = opti.variable(count)
    ds = ca.DM(ds_m)
    opti.subject_to(v[0] == 0)
    opti.subject_to(v[count] == 0)
    opti.subject_to(opti.bounded(0, v, ca.DM(ceiling)))
    opti.subject_to(opti.bounded(0, traction, model.max_traction_force_n))
    opti.subject_to(opti.bounded(0, brake, model.max_brake_force_n))
    average = (v[:-1] + v[1:]) / 2
    opti.subject_to(average >= MIN_AVERAGE_SPEED_MPS)
    deceleration = max_acceleration_mps2 if max_deceleration_mps2 is None else max_deceleration_mps2
    _dynamics(opti, model, (v, traction, brake), ds, track, (deceleration, max_acceleration_mps2))
    _timing(opti, ds / average, nodes_m, duration_s, passing)
    opti.minimize(ca.dot(traction, ds) + 1e-6 * ca.dot(brake**2, ds))
    cruise = distance_m / duration_s * 1.3
    opti.set_initial(v, _initial_speeds(count, cruise, ceiling))
    opti.set_initial(traction, model.davis_a_n)
    opti.solver("ipopt", _ipopt_options(_objective_scale(model, distance_m)))
    solution = opti.solve()
    speeds = np.asarray(solution.value(v), dtype=float)
    forces = np.asarray(solution.value(traction), dtype=float)
    brakes = np.asarray(solution.value(brake), dtype=float)
    return OptimalLeg(
        distances_m=nodes_m,
        speeds_mps=speeds,
        traction_forces_n=forces,
        brake_forces_n=brakes,
        traction_energy_j=float(np.dot(forces, ds_m)),
        duration_s=duration_s,
    )


def _dynamics(
    opti: ca.Opti,
    model: PointMassParameters,
    variables: tuple[ca.MX, ca.MX, ca.MX],
    ds: ca.DM,
    track: list[float],
    bounds_mps2: tuple[float, float],
) -> None:
    """Newton's law over each interval, the traction power and the acceleration's bounds
    (``bounds_mps2``: the largest deceleration and acceleration)."""
    v, traction, brake = variables
    mass = model.mass_kg * (1.0 + model.rotating_mass_factor)
    average = (v[:-1] + v[1:]) / 2
    resistance = (
        model.davis_a_n + model.davis_b_n_per_mps * average + model.davis_c_n_per_mps2 * average**2
    )
    net = traction - brake - resistance - ca.DM(track)
    opti.subject_to(mass * (v[1:] ** 2 - v[:-1] ** 2) / 2 == net * ds)
    opti.subject_to(traction * average <= model.max_traction_power_w)
    deceleration, acceleration = bounds_mps2
    opti.subject_to(opti.bounded(-deceleration, net / mass, acceleration))


def _timing(
    opti: ca.Opti,
    dt: ca.MX,
    nodes_m: FloatArray,
    duration_s: float,
    passing: Sequence[tuple[float, float]],
) -> None:
    """The leg's time, and the time to each passing point's node."""
    opti.subject_to(ca.sum1(dt) == duration_s)
    for offset_m, time_s in passing:
        node = int(np.argmin(np.abs(nodes_m - offset_m)))
        opti.subject_to(ca.sum1(dt[:node]) == time_s)


def _grid_m(distance_m: float, step_m: float, interior_m: Sequence[float]) -> FloatArray:
    """Nodes over the leg [m] from its start: even steps of at most ``step_m`` between the
    ends and the ``interior_m`` offsets, which are nodes; without those, at least four."""
    bounds = sorted({0.0, distance_m, *(min(max(x, 0.0), distance_m) for x in interior_m)})
    if len(bounds) == 2:
        count = max(4, math.ceil(distance_m / step_m))
        return np.linspace(0.0, distance_m, count + 1)
    pieces = [
        np.linspace(a, b, max(1, math.ceil((b - a) / step_m)) + 1)[:-1]
        for a, b in zip(bounds[:-1], bounds[1:], strict=True)
        if b > a
    ]
    return np.concatenate([*pieces, [distance_m]])


def _ceilings_mps(
    track_map: TrackMap,
    model: PointMassParameters,
    start_chainage_m: float,
    distance_m: float,
    cap_mps: float | None,
    nodes: list[float],
) -> list[float]:
    """The speed ceilings the ODP's legs keep, at the nodes [m/s]: the MRSP under the plan's
    margin, held until the train has left a lower limit, and under the ETCS permitted curve
    into each lower limit; the optimum is taken under the same limits as the plans it judges."""
    from onboard.adf.odp_energy import LegTrack  # the legs' module builds on this one

    track = LegTrack(
        track_map,
        model,
        start_chainage_m=start_chainage_m,
        distance_m=distance_m,
        cap_mps=cap_mps,
    )
    ceilings = np.minimum(track.ceilings_mps, track.limit_envelope_mps)
    offsets = np.array(nodes) - start_chainage_m
    return [float(v) for v in np.interp(offsets, track.distances_m, ceilings)]


def _initial_speeds(count: int, cruise_mps: float, ceiling: list[float]) -> FloatArray:
    shape = np.sin(np.linspace(0.0, math.pi, count + 1)) ** 0.5
    return np.minimum(shape * cruise_mps, np.array(ceiling) * 0.95)


def _objective_scale(model: PointMassParameters, distance_m: float) -> float:
    """IPOPT's factor on the objective: one over the rolling resistance's work over the leg
    [1/J], so that the energy it minimises is of the order of one. Unscaled (a few 10⁵ J on a
    ring's leg), its interior point took 270 iterations and seven trial steps each; scaled, a
    third of the time or less, to the same optimum within 10⁻⁸ (docs/perf.md)."""
    return 1.0 / (max(model.davis_a_n, 1.0) * max(distance_m, 1.0))


def _ipopt_options(objective_scale: float = 1.0) -> dict[str, Any]:
    return {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.max_iter": 3000,
        "ipopt.obj_scaling_factor": objective_scale,
    }
