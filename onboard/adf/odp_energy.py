"""Energy-minimised legs for the ODP: LSPB with coasting, its parameters optimised with casadi.

A leg runs in four phases, the regimes of the energy-optimal strategy on level track (DOMAIN.md
§5: accelerate, hold, coast, brake): accelerate at a₁ to the cruise speed v_c, cruise, coast with
no traction from s_c (resistance and gradient slow the train), and brake at a_b from s_b to stop
at the leg's end. The parameters (v_c, a₁, s_c, s_b, a_b) minimise the traction energy at the
wheel subject to arriving at the scheduled time, v_c under the leg's speed limit, the vehicle's
acceleration limit, and the phases in order. The coasting phase is integrated over distance with
the track forces of the line (a casadi interpolant), both in the NLP and, finely, when the
reference is built. The plain LSPB is the start point of the search, so the optimum can only
spend less.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import numpy.typing as npt

from onboard.adf.energy import track_force_n
from onboard.adf.odp import (
    MAX_ACCELERATION_MPS2,
    InfeasibleLegError,
    LegProfile,
    OdpLeg,
    OdpPlan,
    leg_speed_limit_mps,
    lspb_segment,
    plan_legs,
)
from onboard.plant.point_mass import PointMassParameters
from trackdb import TrackMap

__all__ = ["CoastingLeg", "optimise_leg", "plan_energy_legs"]

FloatArray = npt.NDArray[np.float64]
SUBSTEPS = 40
MAX_BRAKING_MPS2 = 0.7
"""Planned braking [m/s²]: service braking with a margin to the URV's 0.93 m/s² full brake,
so the controller can correct a mismatch at the end of a stop."""
FINE_STEP_M = 1.0
SMOOTHING_N = 50.0
MIN_COAST_SPEED_MPS = 0.5
MIN_STEP_M = 0.01
FEASIBILITY_TOLERANCE = 1e-3
ARRIVAL_ITERATIONS = 8
ARRIVAL_TOLERANCE_S = 0.01


@dataclass(frozen=True)
class CoastingLeg:
    """A leg's reference: accelerate, cruise, coast, brake; ``at(t)`` as for an LSPB segment."""

    distance_m: float
    acceleration_mps2: float
    cruise_speed_mps: float
    coast_start_m: float
    brake_start_m: float
    braking_mps2: float
    coast_times_s: FloatArray
    coast_distances_m: FloatArray
    coast_speeds_mps: FloatArray

    @property
    def _accelerating_s(self) -> float:
        return self.cruise_speed_mps / self.acceleration_mps2

    @property
    def _cruise_end_s(self) -> float:
        accelerating_m = self.cruise_speed_mps**2 / (2.0 * self.acceleration_mps2)
        return self._accelerating_s + (self.coast_start_m - accelerating_m) / self.cruise_speed_mps

    @property
    def _brake_start_s(self) -> float:
        return self._cruise_end_s + float(self.coast_times_s[-1])

    @property
    def duration_s(self) -> float:
        return self._brake_start_s + float(self.coast_speeds_mps[-1]) / self.braking_mps2

    def at(self, t_s: float) -> tuple[float, float]:
        """(distance [m], speed [m/s]) at ``t_s`` from the leg's start, clamped to the leg."""
        t = min(max(t_s, 0.0), self.duration_s)
        if t < self._accelerating_s:
            return 0.5 * self.acceleration_mps2 * t * t, self.acceleration_mps2 * t
        if t < self._cruise_end_s:
            accelerating_m = self.cruise_speed_mps**2 / (2.0 * self.acceleration_mps2)
            return accelerating_m + self.cruise_speed_mps * (t - self._accelerating_s), (
                self.cruise_speed_mps
            )
        if t < self._brake_start_s:
            tau = t - self._cruise_end_s
            index = min(bisect.bisect_right(self.coast_times_s, tau), len(self.coast_times_s) - 1)
            index = max(index, 1)
            t0, t1 = self.coast_times_s[index - 1], self.coast_times_s[index]
            share = 0.0 if t1 == t0 else (tau - t0) / (t1 - t0)
            s = self.coast_distances_m[index - 1] + share * (
                self.coast_distances_m[index] - self.coast_distances_m[index - 1]
            )
            v = self.coast_speeds_mps[index - 1] + share * (
                self.coast_speeds_mps[index] - self.coast_speeds_mps[index - 1]
            )
            return float(s), float(v)
        remaining = self.duration_s - t
        return self.distance_m - 0.5 * self.braking_mps2 * remaining**2, (
            self.braking_mps2 * remaining
        )


def optimise_leg(
    track_map: TrackMap,
    model: PointMassParameters,
    *,
    start_chainage_m: float,
    distance_m: float,
    duration_s: float,
    speed_limit_mps: float,
    max_acceleration_mps2: float = MAX_ACCELERATION_MPS2,
    max_braking_mps2: float = MAX_BRAKING_MPS2,
) -> CoastingLeg:
    """The least-traction-energy accelerate/cruise/coast/brake leg arriving at ``duration_s``."""
    lspb = lspb_segment(distance_m, duration_s, speed_limit_mps=speed_limit_mps)
    grid = np.linspace(0.0, distance_m, max(2, math.ceil(distance_m / 5.0)) + 1)
    forces = [track_force_n(track_map, model, start_chainage_m + s) for s in grid]
    track = ca.interpolant("track", "linear", [grid], forces)
    variables, constraints, lower, upper, energy = _leg_problem(
        model, track, distance_m, duration_s, speed_limit_mps, max_acceleration_mps2
    )
    solver = ca.nlpsol(
        "leg", "ipopt", {"x": variables, "f": energy, "g": constraints},
        {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes", "ipopt.max_iter": 300},
    )  # fmt: skip
    a, v = lspb.acceleration_mps2, lspb.cruise_speed_mps
    braking = min(a, max_braking_mps2)
    braking_m = v * v / (2 * braking)
    guess = [v, a, distance_m - braking_m - 1.0, distance_m - braking_m, braking]
    bounds = _variable_bounds(distance_m, speed_limit_mps, max_acceleration_mps2, max_braking_mps2)
    result = solver(x0=guess, lbg=lower, ubg=upper, **bounds)
    if not solver.stats()["success"] and _violation(result, lower, upper) > FEASIBILITY_TOLERANCE:
        # Near-flat optima (downhill coasting) may stop IPOPT on its iteration limit at a
        # feasible point; only an infeasible end is a failure.
        raise InfeasibleLegError(f"no coasting profile: {solver.stats()['return_status']}")
    v_c, a_1, s_c, _, a_b = (float(x) for x in np.asarray(result["x"]).ravel())
    return _arrive_on_time(
        lambda coast_m: _build_leg(
            track_map, model, start_chainage_m, distance_m, v_c, a_1, coast_m, a_b
        ),
        s_c, duration_s,
    )  # fmt: skip


def _arrive_on_time(
    build: Callable[[float], CoastingLeg], coast_start_m: float, duration_s: float
) -> CoastingLeg:
    """Move the coasting point (secant steps) so that the finely integrated leg arrives at the
    scheduled time: the NLP's coarse coast integration leaves a small error."""
    leg = build(coast_start_m)
    previous_m, previous_error = coast_start_m, leg.duration_s - duration_s
    step_m = 1.0 if previous_error < 0 else -1.0
    current_m = coast_start_m + step_m
    for _ in range(ARRIVAL_ITERATIONS):
        leg = build(current_m)
        error = leg.duration_s - duration_s
        if abs(error) < ARRIVAL_TOLERANCE_S or error == previous_error:
            break
        current_m, previous_m, previous_error = (
            current_m - error * (current_m - previous_m) / (error - previous_error),
            current_m,
            error,
        )
    return leg


def _violation(result: dict[str, Any], lower: list[float], upper: list[float]) -> float:
    g = np.asarray(result["g"], dtype=float).ravel()
    return float(np.max(np.maximum(np.array(lower) - g, g - np.array(upper)), initial=0.0))


def _variable_bounds(
    distance_m: float, limit_mps: float, max_acceleration_mps2: float, max_braking_mps2: float
) -> dict[str, list[float]]:
    return {
        "lbx": [0.5, 0.05, 0.0, 0.0, 0.05],
        "ubx": [limit_mps, max_acceleration_mps2, distance_m, distance_m, max_braking_mps2],
    }


def _smooth_positive(x: Any) -> Any:
    return 0.5 * (x + ca.sqrt(x * x + SMOOTHING_N**2))


def _leg_problem(
    model: PointMassParameters,
    track: ca.Function,
    distance_m: float,
    duration_s: float,
    limit_mps: float,
    max_acceleration_mps2: float,
) -> tuple[Any, Any, list[float], list[float], Any]:
    mass = model.mass_kg * (1.0 + model.rotating_mass_factor)

    def resistance(v: Any) -> Any:
        return model.davis_a_n + model.davis_b_n_per_mps * v + model.davis_c_n_per_mps2 * v * v

    x = ca.SX.sym("x", 5)
    v_c, a_1, s_c, s_b, a_b = x[0], x[1], x[2], x[3], x[4]
    s_1 = v_c * v_c / (2 * a_1)
    energy: Any = 0
    h_1 = s_1 / SUBSTEPS
    for k in range(SUBSTEPS):
        s = (k + 0.5) * h_1
        v = ca.sqrt(2 * a_1 * s)
        energy += _smooth_positive(mass * a_1 + resistance(v) + track(s)) * h_1
    h_2 = (s_c - s_1) / SUBSTEPS
    for k in range(SUBSTEPS):
        energy += _smooth_positive(resistance(v_c) + track(s_1 + (k + 0.5) * h_2)) * h_2
    h_3 = (s_b - s_c) / SUBSTEPS
    v2 = v_c * v_c
    coast_time: Any = 0
    speeds = []
    for k in range(SUBSTEPS):
        v_now = ca.sqrt(ca.fmax(v2, 1e-4))
        v2_next = v2 - 2 * (resistance(v_now) + track(s_c + k * h_3)) / mass * h_3
        coast_time += 2 * h_3 / (v_now + ca.sqrt(ca.fmax(v2_next, 1e-4)))
        v2 = v2_next
        speeds.append(v2)
    v_b = ca.sqrt(ca.fmax(v2, 1e-4))
    total_time = v_c / a_1 + (s_c - s_1) / v_c + coast_time + v_b / a_b
    constraints = [
        total_time - duration_s,
        v2 - 2 * a_b * (distance_m - s_b),
        s_c - s_1,
        s_b - s_c,
        *speeds,
    ]
    lower = [0.0, 0.0, 0.0, 0.0] + [MIN_COAST_SPEED_MPS**2] * SUBSTEPS
    upper = [0.0, 0.0, distance_m, distance_m] + [limit_mps**2] * SUBSTEPS
    del max_acceleration_mps2  # bounded through the variables
    return x, ca.vertcat(*constraints), lower, upper, energy


def _build_leg(
    track_map: TrackMap,
    model: PointMassParameters,
    start_chainage_m: float,
    distance_m: float,
    cruise_mps: float,
    acceleration_mps2: float,
    coast_start_m: float,
    braking_mps2: float,
) -> CoastingLeg:
    """Integrate the coast finely on the real line until it meets the braking curve that stops
    the train at the leg's end."""
    mass = model.mass_kg * (1.0 + model.rotating_mass_factor)
    accelerating_m = cruise_mps**2 / (2.0 * acceleration_mps2)
    coast_start_m = min(max(coast_start_m, accelerating_m), distance_m)
    times, distances, speeds = [0.0], [coast_start_m], [cruise_mps]
    s, v, t = coast_start_m, cruise_mps, 0.0
    while (gap := distance_m - s - v * v / (2.0 * braking_mps2)) > MIN_STEP_M:
        h = min(FINE_STEP_M, gap)
        resistance = (
            model.davis_a_n + model.davis_b_n_per_mps * v + model.davis_c_n_per_mps2 * v * v
        )
        force = resistance + track_force_n(track_map, model, start_chainage_m + s)
        v_next = math.sqrt(max(v * v - 2.0 * force / mass * h, MIN_COAST_SPEED_MPS**2))
        t += 2.0 * h / (v + v_next)
        s, v = s + h, v_next
        times.append(t)
        distances.append(s)
        speeds.append(v)
    braking = v * v / (2.0 * max(distance_m - s, 1e-6))
    return CoastingLeg(
        distance_m=distance_m, acceleration_mps2=acceleration_mps2, cruise_speed_mps=cruise_mps,
        coast_start_m=coast_start_m, brake_start_m=s, braking_mps2=braking,
        coast_times_s=np.array(times), coast_distances_m=np.array(distances),
        coast_speeds_mps=np.array(speeds),
    )  # fmt: skip


def plan_energy_legs(
    track_map: TrackMap,
    model: PointMassParameters,
    *,
    start_chainage_m: float,
    stops: list[tuple[float, float, float]],
    cap_mps: float | None = None,
) -> tuple[OdpPlan, int]:
    """Plan stop to stop with energy-minimised legs; ``stops`` as for :func:`plan_legs`.

    Returns the plan and how many legs kept the plain LSPB because no coasting profile was
    found for them (the LSPB is always a valid plan).
    """
    baseline = plan_legs(track_map, start_chainage_m=start_chainage_m, stops=stops, cap_mps=cap_mps)
    legs: list[OdpLeg] = []
    kept_plain = 0
    for leg in baseline.legs:
        segment = leg.segment
        limit = leg_speed_limit_mps(
            track_map, start_chainage_m + leg.start_distance_m, segment.distance_m
        )
        if cap_mps is not None:
            limit = min(limit, cap_mps)
        try:
            optimised: LegProfile = optimise_leg(
                track_map, model, start_chainage_m=start_chainage_m + leg.start_distance_m,
                distance_m=segment.distance_m, duration_s=segment.duration_s,
                speed_limit_mps=limit,
            )  # fmt: skip
        except InfeasibleLegError:
            optimised, kept_plain = segment, kept_plain + 1
        legs.append(OdpLeg(leg.start_s, leg.start_distance_m, optimised))
    plan = OdpPlan(legs, start_chainage_m=start_chainage_m, track_map=track_map, cap_mps=cap_mps)
    return plan, kept_plain
