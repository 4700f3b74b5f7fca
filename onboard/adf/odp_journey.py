"""A journey's energy-minimised plan: every stop-to-stop leg, its passing points as time
constraints, and a counted, reasoned fallback where no energy-minimised profile exists.

Each leg is planned by :func:`onboard.adf.odp_energy.optimise_leg`. When that finds no on-time
profile, the leg is planned again with relaxed braking rates, in this order (the first that
arrives on time is kept): the stop's rate raised to the plain LSPB's own deceleration (the
LSPB's blends may be harder than the planned 0.7 m/s²), then braking into lower limits at the
stop's rate (a replan's last resort). Only when none arrives on time does the leg keep the plain
LSPB: a *fallback*, recorded with its reason (:class:`LegFallback`) and counted.

A passing timing point inside a leg splits it: the part up to the point arrives there at its
passing time with a speed v_p (its final braking ends at v_p instead of a stop), the rest
starts from the speed the first part ends with. Pontryagin's principle with an interior time
constraint gives the same structure on each side, with a different holding speed (the costate
jumps at the point): the parts are planned as legs of their own and v_p is chosen by a scalar
search for the least energy of the whole leg. Several passing points in a leg are fixed one
after the other, each with the rest of the leg planned as one part (exact for one point).
A passing time that no profile meets is recorded (:class:`PassingMiss`), and the leg is planned
without it.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from onboard.adf.odp import InfeasibleLegError, LegProfile, OdpLeg, OdpPlan, plan_legs
from onboard.adf.odp_energy import (
    CRAWL_MPS,
    LIMIT_BRAKING_MPS2,
    MAX_BRAKING_MPS2,
    LegTrack,
    ProfileLeg,
    optimise_leg,
)
from onboard.plant.point_mass import PointMassParameters
from trackdb import TrackMap

__all__ = [
    "EnergyPlan",
    "LegFallback",
    "PassingMiss",
    "PassingPoint",
    "join_profiles",
    "plan_energy_journey",
]

_log = logging.getLogger(__name__)

PASSING_SPEED_SAMPLES = 5
"""Passing speeds tried over (0, the ceiling at the point] before the local search."""
PASSING_SPEED_TOLERANCE_MPS = 0.1
NO_PROFILE_J = 1e30
"""The energy [J] the passing-speed search gives a speed with no on-time profile."""


@dataclass(frozen=True)
class PassingPoint:
    """A passing timing point: where (distance travelled from the journey's start [m]) and
    when (time from the journey's start [s]) the train passes it."""

    timing_point_id: str
    distance_m: float
    time_s: float


@dataclass(frozen=True)
class LegFallback:
    """A leg that kept the plain LSPB: which, and why no energy-minimised profile was kept."""

    leg: int
    reason: str


@dataclass(frozen=True)
class PassingMiss:
    """A passing timing point whose time no profile of its leg meets (the leg ignores it)."""

    timing_point_id: str
    reason: str


@dataclass(frozen=True)
class EnergyPlan:
    plan: OdpPlan
    fallbacks: tuple[LegFallback, ...]
    passing_missed: tuple[PassingMiss, ...] = ()

    @property
    def kept_plain(self) -> int:
        """Legs that kept the plain LSPB (the meaning of ``energy_plan_fallbacks``)."""
        return len(self.fallbacks)


@dataclass(frozen=True)
class _Leg:
    """One stop-to-stop leg to plan: from ``start_chainage_m`` over ``distance_m`` in
    ``duration_s``, with the passing points inside it as (offset [m], time from the leg's
    departure [s], timing point id)."""

    start_chainage_m: float
    distance_m: float
    duration_s: float
    passing: tuple[tuple[float, float, str], ...]


def plan_energy_journey(
    track_map: TrackMap,
    model: PointMassParameters,
    *,
    start_chainage_m: float,
    stops: list[tuple[float, float, float]],
    passing: Sequence[PassingPoint] = (),
    cap_mps: float | None = None,
) -> EnergyPlan:
    """Plan stop to stop with energy-minimised legs; ``stops`` as for :func:`plan_legs`.

    Raises
    ------
    InfeasibleLegError
        When the plain LSPB of a leg is infeasible too (the journey cannot be planned).
    """
    baseline = plan_legs(track_map, start_chainage_m=start_chainage_m, stops=stops, cap_mps=cap_mps)
    legs: list[OdpLeg] = []
    fallbacks: list[LegFallback] = []
    missed: list[PassingMiss] = []
    for index, leg in enumerate(baseline.legs):
        segment = leg.segment
        end_m = leg.start_distance_m + segment.distance_m
        inside = tuple(
            (p.distance_m - leg.start_distance_m, p.time_s - leg.start_s, p.timing_point_id)
            for p in sorted(passing, key=lambda p: p.distance_m)
            if leg.start_distance_m < p.distance_m < end_m
        )
        task = _Leg(
            start_chainage_m + leg.start_distance_m, segment.distance_m, segment.duration_s, inside
        )
        deceleration = min(
            float(getattr(segment, "acceleration_mps2", MAX_BRAKING_MPS2)),
            model.max_brake_force_n / (model.mass_kg * (1.0 + model.rotating_mass_factor)),
        )
        try:
            optimised: LegProfile = _plan_leg(track_map, model, task, cap_mps, deceleration, missed)
        except InfeasibleLegError as exc:
            optimised = segment
            fallbacks.append(LegFallback(index, str(exc)))
            _log.warning("energy plan: leg %d keeps the plain LSPB: %s", index, exc)
        legs.append(OdpLeg(leg.start_s, leg.start_distance_m, optimised))
    for miss in missed:
        _log.warning("energy plan: passing point %s missed: %s", miss.timing_point_id, miss.reason)
    plan = OdpPlan(legs, start_chainage_m=start_chainage_m, track_map=track_map, cap_mps=cap_mps)
    return EnergyPlan(plan, tuple(fallbacks), tuple(missed))


def _rates(lspb_deceleration_mps2: float) -> list[tuple[float, float | None]]:
    """(braking into the stop, braking into lower limits) [m/s²], in the order tried."""
    harder = max(MAX_BRAKING_MPS2, lspb_deceleration_mps2)
    rates: list[tuple[float, float | None]] = [(MAX_BRAKING_MPS2, LIMIT_BRAKING_MPS2)]
    if harder > MAX_BRAKING_MPS2:
        rates.append((harder, LIMIT_BRAKING_MPS2))
    rates.append((harder, None))
    return rates


def _plan_leg(
    track_map: TrackMap,
    model: PointMassParameters,
    leg: _Leg,
    cap_mps: float | None,
    lspb_deceleration_mps2: float,
    missed: list[PassingMiss],
) -> ProfileLeg:
    """The leg's profile at the first braking rates that give one on time.

    Raises
    ------
    InfeasibleLegError
        When none does (with the last reason).
    """
    error = InfeasibleLegError("no braking rate tried")
    for braking, limit_braking in _rates(lspb_deceleration_mps2):
        planner = _PartPlanner(track_map, model, cap_mps, braking, limit_braking)
        try:
            return planner.leg(leg, missed)
        except InfeasibleLegError as exc:
            error = exc
    raise error


@dataclass(frozen=True)
class _PartPlanner:
    """Plans the parts of a leg between its passing points at given braking rates."""

    track_map: TrackMap
    model: PointMassParameters
    cap_mps: float | None
    braking_mps2: float
    limit_braking_mps2: float | None

    def part(
        self,
        from_m: float,
        distance_m: float,
        duration_s: float,
        *,
        initial_mps: float = 0.0,
        final_mps: float = 0.0,
        descents: bool = True,
    ) -> ProfileLeg:
        return optimise_leg(
            self.track_map,
            self.model,
            start_chainage_m=from_m,
            distance_m=distance_m,
            duration_s=duration_s,
            cap_mps=self.cap_mps,
            initial_speed_mps=initial_mps,
            braking_mps2=self.braking_mps2,
            limit_braking_mps2=self.limit_braking_mps2,
            final_speed_mps=final_mps,
            descents=descents,
        )

    def leg(self, leg: _Leg, missed: list[PassingMiss]) -> ProfileLeg:
        """The whole leg, its passing points kept where possible (the misses appended)."""
        parts: list[ProfileLeg] = []
        done_m, done_s, speed = 0.0, 0.0, 0.0
        for offset_m, time_s, point_id in leg.passing:
            try:
                first = self._to_passing(leg, done_m, done_s, speed, offset_m, time_s)
            except InfeasibleLegError as exc:
                if not any(m.timing_point_id == point_id for m in missed):
                    missed.append(PassingMiss(point_id, str(exc)))
                continue
            parts.append(first)
            done_m, done_s, speed = offset_m, time_s, float(first.speeds_mps[-1])
        parts.append(
            self.part(
                leg.start_chainage_m + done_m,
                leg.distance_m - done_m,
                leg.duration_s - done_s,
                initial_mps=speed,
            )
        )
        return join_profiles(parts)

    def _to_passing(
        self,
        leg: _Leg,
        done_m: float,
        done_s: float,
        speed_mps: float,
        offset_m: float,
        time_s: float,
    ) -> ProfileLeg:
        """The part from ``done_m`` to the passing point at ``offset_m``, with the passing
        speed that gives the least energy up to the leg's stop."""
        from_m = leg.start_chainage_m + done_m
        length, duration = offset_m - done_m, time_s - done_s
        rest_m, rest_s = leg.distance_m - offset_m, leg.duration_s - time_s
        if length <= 0.0 or duration <= 0.0 or rest_m <= 0.0 or rest_s <= 0.0:
            raise InfeasibleLegError(f"passing at {offset_m:.0f} m, {time_s:.1f} s: out of order")
        ceiling = _ceiling_near_end(self.track_map, self.model, from_m, length, self.cap_mps)
        cache: dict[float, float] = {}

        def energy(passing_mps: float) -> float:
            key = round(passing_mps, 6)
            if key not in cache:
                parts = ((from_m, length, duration), (from_m + length, rest_m, rest_s))
                cache[key] = self._split_energy_j(parts, speed_mps, passing_mps)
            return cache[key]

        grid = np.linspace(CRAWL_MPS, ceiling, PASSING_SPEED_SAMPLES).tolist()
        values = [energy(v) for v in grid]
        best = int(np.argmin(values))
        if values[best] >= NO_PROFILE_J:
            raise InfeasibleLegError(
                f"no profile passes {offset_m:.0f} m into the leg at {time_s:.1f} s"
            )
        low, high = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
        result = minimize_scalar(
            energy,
            bounds=(low, high),
            method="bounded",
            options={"xatol": PASSING_SPEED_TOLERANCE_MPS},
        )
        chosen = min((float(result.x), grid[best]), key=energy)
        # The search leaves out the coasting into descents (ten times the time); the part
        # kept has it.
        return self.part(from_m, length, duration, initial_mps=speed_mps, final_mps=chosen)

    def _split_energy_j(
        self,
        parts: tuple[tuple[float, float, float], tuple[float, float, float]],
        initial_mps: float,
        passing_mps: float,
    ) -> float:
        """Traction energy [J] of the two parts (from [m], length [m], duration [s]) split at
        a passing point passed at ``passing_mps``, without the descents' search; or
        :data:`NO_PROFILE_J` when either has no on-time profile."""
        (first_m, first_length, first_s), (rest_from, rest_m, rest_s) = parts
        try:
            first = self.part(
                first_m,
                first_length,
                first_s,
                initial_mps=initial_mps,
                final_mps=passing_mps,
                descents=False,
            )
            rest = self.part(
                rest_from, rest_m, rest_s, initial_mps=float(first.speeds_mps[-1]), descents=False
            )
        except InfeasibleLegError:
            return NO_PROFILE_J
        return first.traction_energy_j + rest.traction_energy_j


def _ceiling_near_end(
    track_map: TrackMap,
    model: PointMassParameters,
    from_m: float,
    length_m: float,
    cap_mps: float | None,
) -> float:
    """The plan's lowest ceiling over the last few metres before a passing point [m/s]."""
    track = LegTrack(
        track_map, model, start_chainage_m=from_m, distance_m=length_m, cap_mps=cap_mps
    )
    ceilings = np.minimum(track.ceilings_mps, track.limit_envelope_mps)
    return float(np.min(ceilings[-3:]))


def join_profiles(parts: Sequence[ProfileLeg]) -> ProfileLeg:
    """One profile from consecutive parts (each starting where, and as fast as, the one
    before ends)."""
    if len(parts) == 1:
        return parts[0]
    distances, speeds, times = [parts[0].distances_m], [parts[0].speeds_mps], [parts[0].times_s]
    offset_m, offset_s = parts[0].distance_m, parts[0].duration_s
    for part in parts[1:]:
        distances.append(part.distances_m[1:] + offset_m)
        speeds.append(part.speeds_mps[1:])
        times.append(part.times_s[1:] + offset_s)
        offset_m += part.distance_m
        offset_s += part.duration_s
    return ProfileLeg(
        distances_m=np.concatenate(distances),
        speeds_mps=np.concatenate(speeds),
        times_s=np.concatenate(times),
        holding_speed_mps=max(p.holding_speed_mps for p in parts),
        braking_onset_mps=parts[-1].braking_onset_mps,
        traction_energy_j=math.fsum(p.traction_energy_j for p in parts),
    )
