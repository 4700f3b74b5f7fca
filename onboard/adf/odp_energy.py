"""Energy-minimised legs for the ODP: hold, coast and brake on the line's own speed sections.

The energy-optimal control of a train over a fixed time (DOMAIN.md §5) runs in regimes:
accelerate as hard as allowed, hold a speed, coast, brake. Where the speed limit changes inside a
leg, the held speed is capped section by section, so a leg is a chain of LSPB-like segments, one
per speed section: this planner builds that chain from two parameters and optimises them.

Given a holding speed V and the point c where the final coast starts, the profile v(s) over the
leg's distance s is built on a grid of step h:

- the target of section k is w_k = min(V, limit_k), limit_k being the MRSP (with TSRs) and the
  journey cap;
- braking envelope b: backwards from the stop and from every drop of the target, at the planned
  service deceleration a_b;
- coasting curves k: backwards from every drop, the speeds from which coasting meets the lower
  target at the drop, integrated over the line's gradients and curves;
- forwards: below k, accelerate at min(a_max, (F_avail(v) − R(v) − F_track) / M(1 + ρ)) up to
  the target and hold it (traction, or braking on a steep descent, which costs no traction), or
  up to k; on or above k, coast (no traction: v² drops by 2 (R + F_track) / M(1 + ρ) per metre),
  so the train slows for a lower limit without braking where the distance allows; never above
  b. From c on, coast the same way to the final braking curve.

Time T(V, c) = Σ 2h / (v_i + v_{i+1}); traction energy E = Σ max(M(1+ρ) Δv²/2h + R + F_track, 0) h.
For each V the coast point c(V) that arrives exactly on time is the root of T(V, c) − T (T falls
as c grows); E(V, c(V)) is then minimised over V between the slowest holding speed that still
arrives on time without coasting and the highest limit on the leg, by a bounded scalar search.
Both searches are one-dimensional, continuous (c acts through a fractional step) and always find
a profile when the leg is feasible, which the earlier IPOPT formulation of the same structure did
not on descents, where coasting gains speed and must be held by the brake (docs/decisions.md).

The same builder, with V and c given, replans from a moving train (``replan_from_state``): a
shortened movement authority, a new TSR, an obstacle, or the end of an ETCS intervention.
"""

from __future__ import annotations

import bisect
import contextlib
import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.optimize import brentq, minimize_scalar

from onboard.adf.energy import track_force_n
from onboard.adf.odp import (
    MAX_ACCELERATION_MPS2,
    SPEED_OVERREAD_SHARE,
    SPEED_UNDERREAD_SHARE,
    InfeasibleLegError,
    OdpLeg,
    OdpPlan,
    held_under,
)
from onboard.plant.point_mass import MIN_POWER_SPEED_MPS, PointMassParameters
from onboard.runtime.compiled import compiled
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap

__all__ = [
    "LIMIT_BRAKING_MPS2",
    "MAX_BRAKING_MPS2",
    "LegTrack",
    "ProfileLeg",
    "build_profile",
    "optimise_leg",
    "plan_energy_legs",
    "replan_from_state",
]

FloatArray = npt.NDArray[np.float64]
MAX_BRAKING_MPS2 = 0.7
"""Planned braking [m/s²]: service braking with a margin to the URV's 0.93 m/s² full brake,
so the controller can correct a mismatch at the end of a stop."""
MIN_STEP_M = 1.0
MAX_STEPS = 1500
CRAWL_MPS = 0.5
"""The coast never lets the train fall below this speed: traction holds it."""
SPEED_TOLERANCE_MPS = 1e-3
TIME_TOLERANCE_S = 1e-4
ARRIVAL_TOLERANCE_S = 0.05
MIN_DIP, DIP_TOLERANCE, PROBE_DIP, DIP_MIN_SAVING = 0.8, 0.02, 0.95, 1e-3
"""The dip searched: the train coasts into a steep descent down to at least this share of its
target speed; the search stops within this share; it is searched only if the probe dip saves
at least the last share of the energy."""
LIMIT_BRAKING_MPS2 = 0.5
"""Planned braking into a lower speed limit [m/s²], after :data:`LIMIT_REACTION_S`: ETCS
supervises a speed decrease on an EBD-based curve whose permitted speed runs the reaction and
brake build-up times ahead of the emergency deceleration, from the train's max safe front end;
a plan braking into the limit as into a stop crosses it (docs/decisions.md, "Braking into a lower
limit")."""
RECOVERY_BRAKING_MPS2 = MAX_BRAKING_MPS2
"""Braking [m/s²] of a train that is faster than its envelope where a plan starts (a TSR, a
cap or an EoA that came into force inside its braking distance, an overshoot of a limit): the
plan brakes at this rate from the train's speed and re-enters the envelope where they meet."""
LIMIT_REACTION_S = 6.0
"""The permitted curve of a speed decrease as the planner takes it: this long at the speed, then
braking at :data:`LIMIT_BRAKING_MPS2` (the URV's permitted curve is about 4.3 s and 0.59 m/s²)."""
TRAIN_LENGTH_M = 10.0
"""The URV's length [m]: a limit rises only when the train's rear has left the lower one."""
ODOMETRY_FIXED_M, ODOMETRY_SHARE = 10.0, 0.05
"""ETCS's odometry interval: the max safe front end runs this far [m] plus this share of the
distance since the last balise group ahead of the estimate; the planner brakes that much earlier."""
MRSP_MARGIN_MPS = 0.2 * MPS_PER_KMH
"""The plan holds this far under the MRSP (not under the journey's cap), so that tracking
errors of the controller under a model mismatch stay under the limit."""


@dataclass(frozen=True)
class ProfileLeg:
    """A leg's reference as a speed profile over distance; ``at(t)`` as for an LSPB segment.

    Between grid points the acceleration is constant, so distance and speed at any time are
    exact for the profile and consistent with each other.
    """

    distances_m: FloatArray
    speeds_mps: FloatArray
    times_s: FloatArray
    holding_speed_mps: float
    braking_onset_mps: float
    traction_energy_j: float
    _lists: tuple[list[float], list[float], list[float]] = field(
        init=False, repr=False, compare=False
    )
    """The three series as Python floats: :meth:`at` runs some 100 times per control step, and
    bisecting or indexing an array makes a NumPy scalar per access (the values are the same)."""

    def __post_init__(self) -> None:
        lists = (self.distances_m.tolist(), self.speeds_mps.tolist(), self.times_s.tolist())
        object.__setattr__(self, "_lists", lists)

    @property
    def distance_m(self) -> float:
        return float(self.distances_m[-1])

    @property
    def duration_s(self) -> float:
        return float(self.times_s[-1])

    @property
    def max_speed_mps(self) -> float:
        return float(self.speeds_mps.max())

    def at(self, t_s: float) -> tuple[float, float]:
        """(distance [m], speed [m/s]) at ``t_s`` from the leg's start, clamped to the leg."""
        distances, speeds, times = self._lists
        t = min(max(t_s, 0.0), times[-1])
        index = min(max(bisect.bisect_right(times, t) - 1, 0), len(times) - 2)
        t0, t1 = times[index], times[index + 1]
        v0, v1 = speeds[index], speeds[index + 1]
        tau = t - t0
        acceleration = (v1 - v0) / (t1 - t0) if t1 > t0 else 0.0
        s = distances[index] + v0 * tau + 0.5 * acceleration * tau * tau
        return min(s, distances[index + 1]), v0 + acceleration * tau


class LegTrack:
    """What the builder needs of the line over one leg, sampled once on the grid.

    ``ceilings`` are the MRSP less a small margin (and the cap) at each grid point, the lowest
    one touching the point's neighbouring steps, so that a profile under them is under the
    MRSP everywhere.
    """

    def __init__(
        self,
        track_map: TrackMap,
        model: PointMassParameters,
        *,
        start_chainage_m: float,
        distance_m: float,
        cap_mps: float | None = None,
        max_acceleration_mps2: float = MAX_ACCELERATION_MPS2,
        braking_mps2: float = MAX_BRAKING_MPS2,
        limit_braking_mps2: float | None = LIMIT_BRAKING_MPS2,
        final_speed_mps: float = 0.0,
    ) -> None:
        if not (math.isfinite(distance_m) and distance_m > 0.0):
            raise InfeasibleLegError(f"leg of {distance_m} m")
        steps = max(2, math.ceil(distance_m / MIN_STEP_M))
        steps = min(steps, MAX_STEPS)
        self.model = model
        self.step_m = distance_m / steps
        self.distances_m = np.linspace(0.0, distance_m, steps + 1)
        self.ceilings_mps = self._ceilings(track_map, start_chainage_m, cap_mps)
        if not np.all(np.isfinite(self.ceilings_mps)):
            raise InfeasibleLegError("the leg runs beyond the end of the line")
        middles = start_chainage_m + (self.distances_m[:-1] + self.distances_m[1:]) / 2.0
        self.track_forces_n = np.array([track_force_n(track_map, model, c) for c in middles])
        self.effective_mass_kg = model.mass_kg * (1.0 + model.rotating_mass_factor)
        self.max_acceleration_mps2 = max_acceleration_mps2
        self.braking_mps2 = braking_mps2
        """Into the stop at the leg's end [m/s²]."""
        self.final_speed_mps = max(final_speed_mps, 0.0)
        """The speed at the leg's end [m/s]: 0 at a stop, the passing speed at a passing point
        (the leg is then the part of a stop-to-stop leg up to it)."""
        self.keeps_permitted_curves = limit_braking_mps2 is not None
        """Whether the plan keeps under the ETCS permitted curve of each drop of the limits; not
        when ``limit_braking_mps2`` is None, a replan's last resort, which brakes into the
        limits as into the stop."""
        self.limit_braking_mps2 = (
            braking_mps2 if limit_braking_mps2 is None else min(limit_braking_mps2, braking_mps2)
        )
        """Into a lower speed limit inside the leg [m/s²] (never harder than into the stop)."""
        self.limit_envelope_mps = self._limit_envelope(track_map, start_chainage_m)
        """The highest speed at each grid point from which the ETCS permitted curve of every
        drop of the ceilings ahead is kept, as :data:`LIMIT_REACTION_S` and the odometry
        interval make it [m/s] (infinite before no drop)."""

    def _ceilings(
        self, track_map: TrackMap, start_chainage_m: float, cap_mps: float | None
    ) -> FloatArray:
        """The MRSP under the plan's margins (and the cap) at each grid point [m/s]."""
        steps = len(self.distances_m) - 1
        cap = math.inf if cap_mps is None else held_under(cap_mps, MRSP_MARGIN_MPS)
        ceilings = np.full(steps + 1, cap)
        sections = track_map.mrsp_window(start_chainage_m, float(self.distances_m[-1]))
        for index, section in enumerate(sections):
            speed_mps = held_under(section.speed_mps, MRSP_MARGIN_MPS)
            if index > 0 and sections[index - 1].speed_mps > section.speed_mps:
                speed_mps -= (SPEED_OVERREAD_SHARE - SPEED_UNDERREAD_SHARE) * section.speed_mps
            to_m = section.to_distance_m
            if index + 1 < len(sections) and sections[index + 1].speed_mps > section.speed_mps:
                # ETCS raises the limit when the rear of the train's min safe front end has
                # left the section: the train length and the odometry interval beyond it.
                beyond = track_map.distance_beyond_balise_group_m(start_chainage_m + to_m)
                to_m += (
                    TRAIN_LENGTH_M
                    + ODOMETRY_FIXED_M
                    + ODOMETRY_SHARE * (to_m if beyond is None else beyond)
                )
            first = max(0, math.floor(section.from_distance_m / self.step_m) - 1)
            last = min(steps, math.ceil(to_m / self.step_m) + 1)
            view = ceilings[first : last + 1]
            np.minimum(view, speed_mps, out=view)
        return ceilings

    def _limit_envelope(self, track_map: TrackMap, start_chainage_m: float) -> FloatArray:
        distances, ceilings = self.distances_m, self.ceilings_mps
        envelope = np.full(len(distances), math.inf)
        drops = np.flatnonzero(ceilings[1:] < ceilings[:-1] - SPEED_TOLERANCE_MPS) + 1
        if not drops.size or not self.keeps_permitted_curves:
            return envelope
        a, reaction_s = self.limit_braking_mps2, LIMIT_REACTION_S
        top = float(ceilings.max())
        for j in drops.tolist():
            low, drop_m = float(ceilings[j]), float(distances[j])
            # The odometry interval is widest where the braking may start: sample the window.
            window_m = top * reaction_s + (top * top - low * low) / (2.0 * a)
            samples = np.linspace(max(drop_m - window_m, 0.0), drop_m, 16)
            beyond = [
                track_map.distance_beyond_balise_group_m(start_chainage_m + d)
                for d in samples.tolist()
            ]
            run_m = max(drop_m if b is None else b for b in beyond)
            room_m = np.maximum(
                drop_m - distances[: j + 1] - ODOMETRY_FIXED_M - ODOMETRY_SHARE * run_m, 0.0
            )
            # v·T + (v² − low²) / 2a = room, solved for v; never under the lower limit itself.
            speeds = -a * reaction_s + np.sqrt((a * reaction_s) ** 2 + low * low + 2.0 * a * room_m)
            np.maximum(speeds, low, out=speeds)
            np.minimum(envelope[: j + 1], speeds, out=envelope[: j + 1])
        return envelope

    @property
    def steps(self) -> int:
        return len(self.distances_m) - 1

    @property
    def distance_m(self) -> float:
        return float(self.distances_m[-1])

    def resistance_n(self, speed_mps: float) -> float:
        m = self.model
        return m.davis_a_n + m.davis_b_n_per_mps * speed_mps + m.davis_c_n_per_mps2 * speed_mps**2

    def available_traction_n(self, speed_mps: float) -> float:
        m = self.model
        return min(
            m.max_traction_force_n, m.max_traction_power_w / max(speed_mps, MIN_POWER_SPEED_MPS)
        )

    def coast_delta_v2(self, index: int, speed_mps: float) -> float:
        """Change of v² [m²/s²] over step ``index`` with no traction and no brake."""
        force = self.resistance_n(speed_mps) + float(self.track_forces_n[index])
        return -2.0 * force / self.effective_mass_kg * self.step_m


class _Profiles:
    """Profiles of one leg for (V, U), with the targets and the braking envelope cached per V."""

    def __init__(
        self,
        track: LegTrack,
        initial_mps: float,
        *,
        brake_down: bool = False,
        dip: float = 1.0,
    ) -> None:
        self.track = track
        self.initial_mps = initial_mps
        self.brake_down = brake_down
        self.dip = dip
        """The speed at the top of each steep descent as a share of the target there: below 1
        the train coasts into the descent from before it (1: it holds the target up to it)."""
        self._descents: dict[float, tuple[FloatArray, npt.NDArray[np.bool_]]] = {}
        self._envelopes: dict[float, tuple[FloatArray, FloatArray]] = {}
        # A train faster than the holding speed slows down to it by coasting (no traction, no
        # loss to the brake), or, when the schedule asks for more time than coasting down can
        # give, by braking at the planned rate: the target follows that curve from the initial
        # speed, never rising.
        coast_down = np.zeros(track.steps + 1)
        v = coast_down[0] = initial_mps
        for i in range(track.steps):
            if v <= CRAWL_MPS:
                break
            if brake_down:
                change = -2.0 * track.braking_mps2 * track.step_m
            else:
                change = min(0.0, track.coast_delta_v2(i, v))
            v = math.sqrt(max(v * v + change, 0.0))
            coast_down[i + 1] = v
        self._coast_down = coast_down

    def envelope(self, holding_mps: float) -> tuple[FloatArray, FloatArray]:
        """Targets w and the braking envelope b for a holding speed."""
        if holding_mps in self._envelopes:
            return self._envelopes[holding_mps]
        track = self.track
        n = track.steps
        targets = np.minimum(track.ceilings_mps, np.maximum(holding_mps, self._coast_down))
        # The holding speed is a target for the traction, not a ceiling: on a descent the
        # train coasts above it up to the limits (no brake, MARECO's downhill coasting); only
        # a train braking down to it (``brake_down``) is held under it.
        envelope = targets.copy() if self.brake_down else track.ceilings_mps.copy()
        envelope[n] = min(track.final_speed_mps, envelope[n])
        two_b_h = 2.0 * track.braking_mps2 * track.step_m
        for i in range(n - 1, -1, -1):
            envelope[i] = min(envelope[i], math.sqrt(envelope[i + 1] ** 2 + two_b_h))
        # Into each drop of the limits the gentler curve the ETCS permitted speed allows.
        np.minimum(envelope, track.limit_envelope_mps, out=envelope)
        if self.initial_mps > envelope[0] + SPEED_TOLERANCE_MPS:
            envelope = self._recovered(envelope)
        self._envelopes[holding_mps] = targets, envelope
        return targets, envelope

    def _recovered(self, envelope: FloatArray) -> FloatArray:
        """The envelope of a train faster than it where the leg starts: braking at
        :data:`RECOVERY_BRAKING_MPS2` from the initial speed until that curve meets the
        envelope, the envelope from there on.

        Raises
        ------
        InfeasibleLegError
            When that braking does not meet the envelope before the leg's end (the stop).
        """
        distances = self.track.distances_m
        recovery_v2 = self.initial_mps**2 - 2.0 * RECOVERY_BRAKING_MPS2 * distances
        recovery = np.sqrt(np.maximum(recovery_v2, 0.0))
        met = np.flatnonzero(recovery <= envelope + SPEED_TOLERANCE_MPS)
        if met.size == 0:
            raise InfeasibleLegError(
                f"{self.initial_mps:.2f} m/s is above what braking at {RECOVERY_BRAKING_MPS2}"
                f" m/s² can bring down to the plan's limits within the leg's"
                f" {self.track.distance_m:.1f} m"
            )
        recovered = envelope.copy()
        recovered[: met[0]] = recovery[: met[0]]
        return recovered

    def coasting_curves(self, targets: FloatArray, onset_mps: float) -> FloatArray:
        """Before each drop of the target and before the stop: the braking curve down from the
        onset speed U (or from the lower target, when higher), and before it the speeds from
        which coasting meets that curve; infinite elsewhere."""
        track = self.track
        n, h = track.steps, track.step_m
        curves = np.full(n + 1, math.inf)
        # Drops of the limits only: the coast-down from a high initial speed is a curve, not
        # a drop to brake for.
        limits = np.minimum(track.ceilings_mps, targets.max())
        ends = np.flatnonzero(limits[1:] < limits[:-1] - SPEED_TOLERANCE_MPS) + 1
        targets_v2 = targets * targets
        track_n = track.track_forces_n
        for end in (*ends[ends < n], n):
            low = track.final_speed_mps if end == n else float(targets[end])
            braking = track.braking_mps2 if end == n else track.limit_braking_mps2
            onset = max(onset_mps, low)
            onset_m = float(track.distances_m[end]) - (onset**2 - low**2) / (2.0 * braking)
            first = min(max(math.floor(onset_m / h), -1), end - 1)
            # The braking part, from the onset point to the end.
            span = np.arange(first + 1, end + 1)
            to_end_m = track.distances_m[end] - track.distances_m[span]
            curves[span] = np.minimum(curves[span], np.sqrt(low**2 + 2.0 * braking * to_end_m))
            if first < 0:
                continue
            # The coasting part, backwards from the onset point.
            force = track.resistance_n(onset) + float(track.track_forces_n[first])
            v2 = onset**2 + 2.0 * force / track.effective_mass_kg * (onset_m - first * h)
            m = track.model
            _coast_backwards(
                curves,
                first,
                v2,
                targets_v2,
                track_n,
                (m.davis_a_n, m.davis_b_n_per_mps, m.davis_c_n_per_mps2),
                2.0 * h / track.effective_mass_kg,
            )
        return curves

    def descent_curves(self, holding_mps: float) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        """Before each steep descent (where coasting at the target gains speed): the speeds
        from which coasting reaches the descent's top at ``dip`` × the target there (infinite
        elsewhere), and the steps of those descents, on which the train coasts (no traction
        below the target either). The train coasts into the descent and gains the speed back
        on it, instead of holding the target up to it (MARECO's coasting before a descent)."""
        if holding_mps in self._descents:
            return self._descents[holding_mps]
        track = self.track
        targets, _ = self.envelope(holding_mps)
        curves = np.full(track.steps + 1, math.inf)
        coast_only = np.zeros(track.steps, dtype=bool)
        if self.dip < 1.0:
            m = track.model
            w = targets[:-1]
            resistance = m.davis_a_n + m.davis_b_n_per_mps * w + m.davis_c_n_per_mps2 * w * w
            gaining = (resistance + track.track_forces_n) < 0.0
            starts = np.flatnonzero(gaining[1:] & ~gaining[:-1]) + 1
            ends = np.flatnonzero(~gaining[1:] & gaining[:-1]) + 1
            for start in starts.tolist():
                self._coast_back(curves, targets, start, self.dip * float(targets[start]))
                later = ends[ends > start]
                coast_only[start : int(later[0]) if later.size else track.steps] = True
        self._descents[holding_mps] = curves, coast_only
        return self._descents[holding_mps]

    def _coast_back(self, curves: FloatArray, targets: FloatArray, end: int, low: float) -> None:
        """Lower ``curves`` before point ``end`` to the coasting curve that ends there at
        ``low`` [m/s], back to where it meets the targets."""
        track = self.track
        m = track.model
        _coast_backwards(
            curves,
            end,
            low * low,
            targets * targets,
            track.track_forces_n,
            (m.davis_a_n, m.davis_b_n_per_mps, m.davis_c_n_per_mps2),
            2.0 * track.step_m / track.effective_mass_kg,
        )

    def speeds(self, holding_mps: float, onset_mps: float) -> FloatArray:
        """The profile: drive below the coasting curves, coast on or above them, never above
        the braking envelope (the planner's hot loop, compiled: :func:`_forward`)."""
        track = self.track
        targets, envelope = self.envelope(holding_mps)
        descent, coast_only = self.descent_curves(holding_mps)
        m = track.model
        return _forward(
            min(self.initial_mps, float(envelope[0])),
            np.minimum(self.coasting_curves(targets, onset_mps), descent),
            envelope * envelope,
            targets * targets,
            track.track_forces_n,
            coast_only,
            (m.davis_a_n, m.davis_b_n_per_mps, m.davis_c_n_per_mps2),
            (m.max_traction_force_n, m.max_traction_power_w, MIN_POWER_SPEED_MPS),
            (track.effective_mass_kg, track.step_m, track.max_acceleration_mps2),
        )

    def time_s(self, holding_mps: float, onset_mps: float) -> float:
        return float(_cumulative(self.track, self.speeds(holding_mps, onset_mps))[0][-1])

    def onset_mps(self, holding_mps: float, duration_s: float) -> float:
        """The braking onset speed U that arrives on time at this holding speed: U = V is the
        fastest (no coasting), a lower U coasts longer."""
        if self.time_s(holding_mps, holding_mps) >= duration_s:
            return holding_mps
        if self.time_s(holding_mps, 0.0) <= duration_s:
            return 0.0
        slack = lambda u: self.time_s(holding_mps, u) - duration_s  # noqa: E731
        return float(brentq(slack, 0.0, holding_mps, xtol=1e-4, rtol=1e-10))

    def energy_j(self, holding_mps: float, duration_s: float) -> float:
        speeds = self.speeds(holding_mps, self.onset_mps(holding_mps, duration_s))
        return float(_cumulative(self.track, speeds)[1][-1])


_jit = compiled()
"""The planner's loops, compiled (they read constants of this module only)."""


@_jit
def _forward(
    initial_mps: float,
    coasting: FloatArray,
    envelope_v2: FloatArray,
    targets_v2: FloatArray,
    track_n: FloatArray,
    coast_only: npt.NDArray[np.bool_],
    davis: tuple[float, float, float],
    traction_limits: tuple[float, float, float],
    motion: tuple[float, float, float],
) -> FloatArray:
    """The forward run of :meth:`_Profiles.speeds` from ``initial_mps`` over the grid:
    ``davis`` (A, B, C), ``traction_limits`` (force, power, the speed below which power does
    not limit), ``motion`` (effective mass, step, largest acceleration). ``min`` and ``max``
    are written out as the built-ins choose."""
    a_n, b_n, c_n = davis
    f_max, p_max, min_power_speed = traction_limits
    mass, h, a_max = motion
    n = track_n.shape[0]
    coast_k = 2.0 * h / mass
    crawl_v2 = CRAWL_MPS * CRAWL_MPS
    v = initial_mps
    out = np.empty(n + 1)
    out[0] = v
    for i in range(n):
        vv = v * v
        resistance = a_n + b_n * v + c_n * vv + track_n[i]
        coast_v2 = vv - coast_k * resistance
        if coast_only[i] or v >= coasting[i] - SPEED_TOLERANCE_MPS:
            v2 = coast_v2
        else:
            traction = f_max
            if v > min_power_speed and p_max < f_max * v:
                traction = p_max / v
            acceleration = (traction - resistance) / mass
            if acceleration > a_max:
                acceleration = a_max
            # Traction up to the target (holding it); coasting where that is faster (a
            # descent, or a train above the target coming down to it).
            v2 = vv + 2.0 * acceleration * h
            if targets_v2[i + 1] < v2:
                v2 = targets_v2[i + 1]
            if coast_v2 > v2:
                v2 = coast_v2
            ceiling_v2 = coasting[i + 1] * coasting[i + 1]
            if v2 > ceiling_v2:
                v2 = ceiling_v2
        if v2 < crawl_v2 and i < n - 1:
            v2 = crawl_v2
        if v2 > envelope_v2[i + 1]:
            v2 = envelope_v2[i + 1]
        v = math.sqrt(v2) if v2 > 0.0 else 0.0
        out[i + 1] = v
    return out


@_jit
def _coast_backwards(
    curves: FloatArray,
    first: int,
    v2: float,
    targets_v2: FloatArray,
    track_n: FloatArray,
    davis: tuple[float, float, float],
    coast_k: float,
) -> None:
    """Lower ``curves`` from point ``first`` backwards to the coasting curve that has v² =
    ``v2`` there, back to where it meets the targets (:meth:`_Profiles.coasting_curves`, and
    ``_coast_back`` before a descent)."""
    a_n, b_n, c_n = davis
    crawl_v2 = CRAWL_MPS**2
    for i in range(first, -1, -1):
        # On a descent coasting gains speed, so backwards the curve falls; it is held at a
        # crawl, as the forward run is, so that a lower U always coasts longer.
        if crawl_v2 > v2:
            v2 = crawl_v2
        if v2 >= targets_v2[i]:
            break
        v = math.sqrt(v2)
        if v < curves[i]:
            curves[i] = v
        if i > 0:
            v2 += coast_k * (a_n + b_n * v + c_n * v2 + track_n[i - 1])


def _cumulative(track: LegTrack, speeds: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Cumulative time [s] and traction energy [J] at each grid point of a profile."""
    h = track.step_m
    v0, v1 = speeds[:-1], speeds[1:]
    average = np.maximum((v0 + v1) / 2.0, 1e-9)
    dt = h / average
    m = track.model
    resistance = m.davis_a_n + m.davis_b_n_per_mps * average + m.davis_c_n_per_mps2 * average**2
    force = track.effective_mass_kg * (v1**2 - v0**2) / (2.0 * h) + resistance
    force += track.track_forces_n
    energy = np.maximum(force, 0.0) * h
    return np.concatenate(([0.0], np.cumsum(dt))), np.concatenate(([0.0], np.cumsum(energy)))


def build_profile(
    track: LegTrack,
    *,
    holding_speed_mps: float,
    braking_onset_mps: float | None = None,
    initial_speed_mps: float = 0.0,
    brake_down: bool = False,
    dip: float = 1.0,
) -> ProfileLeg:
    """The profile for a holding speed V [m/s] and a braking onset speed U [m/s] (V, no
    coasting, when omitted), from ``initial_speed_mps`` to a stop at the leg's end; faster than
    V at the start, the train coasts down to it (or brakes, with ``brake_down``); into each
    steep descent it coasts down to ``dip`` × V."""
    onset = holding_speed_mps if braking_onset_mps is None else braking_onset_mps
    profiles = _Profiles(track, initial_speed_mps, brake_down=brake_down, dip=dip)
    speeds = profiles.speeds(holding_speed_mps, onset)
    times, energies = _cumulative(track, speeds)
    return ProfileLeg(
        distances_m=track.distances_m,
        speeds_mps=speeds,
        times_s=times,
        holding_speed_mps=holding_speed_mps,
        braking_onset_mps=onset,
        traction_energy_j=float(energies[-1]),
    )


def optimise_leg(
    track_map: TrackMap,
    model: PointMassParameters,
    *,
    start_chainage_m: float,
    distance_m: float,
    duration_s: float,
    cap_mps: float | None = None,
    initial_speed_mps: float = 0.0,
    max_acceleration_mps2: float = MAX_ACCELERATION_MPS2,
    braking_mps2: float = MAX_BRAKING_MPS2,
    limit_braking_mps2: float | None = LIMIT_BRAKING_MPS2,
    final_speed_mps: float = 0.0,
    descents: bool = True,
) -> ProfileLeg:
    """The least-traction-energy hold/coast/brake leg arriving after ``duration_s`` [s], at a
    stop (or at most at ``final_speed_mps`` [m/s]: a part of a leg up to a passing point);
    with ``descents``, coasting into steep descents where that saves energy (a search that
    multiplies the planning time by about ten on such legs).

    Raises
    ------
    InfeasibleLegError
        When even holding the highest limits the train cannot arrive in time.
    """
    track = LegTrack(
        track_map,
        model,
        start_chainage_m=start_chainage_m,
        distance_m=distance_m,
        cap_mps=cap_mps,
        max_acceleration_mps2=max_acceleration_mps2,
        braking_mps2=braking_mps2,
        limit_braking_mps2=limit_braking_mps2,
        final_speed_mps=final_speed_mps,
    )
    best: ProfileLeg | None = None
    for brake_down in (False, True) if initial_speed_mps > CRAWL_MPS else (False,):
        leg = _optimise_dips(
            track, duration_s, initial_speed_mps, brake_down=brake_down, descents=descents
        )
        on_time = abs(leg.duration_s - duration_s) <= ARRIVAL_TOLERANCE_S
        if on_time and (best is None or leg.traction_energy_j < best.traction_energy_j):
            best = leg
    if best is None:
        raise InfeasibleLegError(
            f"{distance_m:.0f} m cannot take {duration_s:.1f} s from {initial_speed_mps:.2f} m/s"
        )
    return best


def _optimise_dips(
    track: LegTrack,
    duration_s: float,
    initial_speed_mps: float,
    *,
    brake_down: bool,
    descents: bool = True,
) -> ProfileLeg:
    """:func:`_optimise` without coasting into descents and, on a leg with steep descents,
    with the dip (the share of the target the train coasts down to before each descent) that
    gives the least energy (a bounded scalar search)."""
    legs: dict[float, ProfileLeg | None] = {}

    def leg_for(dip: float) -> ProfileLeg | None:
        if dip not in legs:
            profiles = _Profiles(track, initial_speed_mps, brake_down=brake_down, dip=dip)
            try:
                legs[dip] = _optimise(track, profiles, duration_s, initial_speed_mps)
            except InfeasibleLegError:
                legs[dip] = None
        return legs[dip]

    def energy(dip: float) -> float:
        leg = leg_for(dip)
        on_time = leg is not None and abs(leg.duration_s - duration_s) <= ARRIVAL_TOLERANCE_S
        return leg.traction_energy_j if leg is not None and on_time else math.inf

    plain = _optimise(
        track,
        _Profiles(track, initial_speed_mps, brake_down=brake_down),
        duration_s,
        initial_speed_mps,
    )
    legs[1.0] = plain
    if not descents or not _descents_at(track, plain.holding_speed_mps):
        return plain
    # A probe first: most descents (a 2 ‰ one at 40 km/h) gain too little to pay for the
    # search.
    if energy(PROBE_DIP) >= plain.traction_energy_j * (1.0 - DIP_MIN_SAVING):
        return plain
    result = minimize_scalar(
        energy, bounds=(MIN_DIP, 1.0), method="bounded", options={"xatol": DIP_TOLERANCE}
    )
    best = min((float(result.x), PROBE_DIP, 1.0), key=energy)
    chosen = leg_for(best)
    return plain if chosen is None else chosen


def _descents_at(track: LegTrack, holding_mps: float) -> bool:
    """Whether the leg has a steep descent at this holding speed: a step where coasting at
    the target gains speed after one where it does not."""
    m = track.model
    w = np.minimum(track.ceilings_mps[:-1], holding_mps)
    resistance = m.davis_a_n + m.davis_b_n_per_mps * w + m.davis_c_n_per_mps2 * w * w
    gaining = (resistance + track.track_forces_n) < 0.0
    return bool(np.any(gaining[1:] & ~gaining[:-1]))


def _optimise(
    track: LegTrack, profiles: _Profiles, duration_s: float, initial_speed_mps: float
) -> ProfileLeg:
    fastest = float(track.ceilings_mps.max())
    fastest_s = profiles.time_s(fastest, fastest)
    if fastest_s > duration_s + TIME_TOLERANCE_S:
        raise InfeasibleLegError(
            f"{track.distance_m:.0f} m takes at least {fastest_s:.1f} s under the limits, more "
            f"than the {duration_s:.1f} s scheduled"
        )
    # The slowest holding speed that arrives on time without coasting.
    slowest = CRAWL_MPS
    if profiles.time_s(CRAWL_MPS, CRAWL_MPS) > duration_s:
        slowest = float(
            brentq(lambda v: profiles.time_s(v, v) - duration_s, CRAWL_MPS, fastest, xtol=1e-6)
        )
    # The fastest holding speed from which the longest coast still does not arrive early.
    highest = fastest
    if profiles.time_s(fastest, 0.0) < duration_s <= profiles.time_s(slowest, 0.0):
        highest = float(
            brentq(lambda v: profiles.time_s(v, 0.0) - duration_s, slowest, fastest, xtol=1e-6)
        )
    result = minimize_scalar(
        lambda v: profiles.energy_j(v, duration_s),
        bounds=(slowest, highest),
        method="bounded",
        options={"xatol": 5e-3},
    )
    holding = min((float(result.x), slowest), key=lambda v: profiles.energy_j(v, duration_s))
    return build_profile(
        track,
        holding_speed_mps=holding,
        braking_onset_mps=profiles.onset_mps(holding, duration_s),
        initial_speed_mps=initial_speed_mps,
        brake_down=profiles.brake_down,
        dip=profiles.dip,
    )


def plan_energy_legs(
    track_map: TrackMap,
    model: PointMassParameters,
    *,
    start_chainage_m: float,
    stops: list[tuple[float, float, float]],
    cap_mps: float | None = None,
) -> tuple[OdpPlan, int]:
    """Plan stop to stop with energy-minimised legs; ``stops`` as for :func:`plan_legs`.

    Returns the plan and how many legs kept the plain LSPB because no energy-minimised profile
    arrives on time for them (:func:`onboard.adf.odp_journey.plan_energy_journey`, which also
    gives the reasons and takes passing points).
    """
    from onboard.adf.odp_journey import plan_energy_journey  # it builds on this module

    planned = plan_energy_journey(
        track_map, model, start_chainage_m=start_chainage_m, stops=stops, cap_mps=cap_mps
    )
    return planned.plan, planned.kept_plain


def replan_from_state(
    track_map: TrackMap,
    model: PointMassParameters,
    *,
    now_s: float,
    start_chainage_m: float,
    distance_m: float,
    speed_mps: float,
    stop_distance_m: float,
    cruise_mps: float,
    arrival_s: float | None = None,
    braking_mps2: float = MAX_BRAKING_MPS2,
    limit_braking_mps2: float | None = LIMIT_BRAKING_MPS2,
) -> OdpPlan:
    """A plan from the current reference (distance travelled and speed at ``now_s``) to a stop
    ``stop_distance_m`` further on: a shortened MA, an obstacle, the EoA after an ETCS
    intervention, or the same stop under a new TSR.

    The profile follows the MRSP section by section (a new TSR included) and never exceeds it or
    ``cruise_mps``. Without ``arrival_s`` it holds ``cruise_mps`` and brakes at the end; with
    it, it arrives at ``arrival_s`` with the least traction energy when that is possible, else
    as early as the limits allow.

    Raises
    ------
    InfeasibleLegError
        When the stop is closer than the planned braking allows from ``speed_mps``.
    """
    profile = _replanned_profile(
        track_map,
        model,
        start_chainage_m=start_chainage_m + distance_m,
        distance_m=stop_distance_m,
        duration_s=None if arrival_s is None else arrival_s - now_s,
        cruise_mps=cruise_mps,
        initial_speed_mps=speed_mps,
        braking_mps2=braking_mps2,
        limit_braking_mps2=limit_braking_mps2,
    )
    return OdpPlan(
        [OdpLeg(now_s, distance_m, profile)],
        start_chainage_m=start_chainage_m,
        track_map=track_map,
        cap_mps=cruise_mps,
    )


def _replanned_profile(
    track_map: TrackMap,
    model: PointMassParameters,
    *,
    start_chainage_m: float,
    distance_m: float,
    duration_s: float | None,
    cruise_mps: float,
    initial_speed_mps: float,
    braking_mps2: float,
    limit_braking_mps2: float | None,
) -> ProfileLeg:
    """:func:`replan_from_state`'s leg: on time (after ``duration_s`` [s]) with the least
    traction energy when that is given and possible, else holding ``cruise_mps`` and braking at
    the end (as early as the limits allow).

    Raises
    ------
    InfeasibleLegError
        When the stop is closer than the planned braking allows from ``initial_speed_mps``.
    """
    if duration_s is not None:
        with contextlib.suppress(InfeasibleLegError):
            return optimise_leg(
                track_map,
                model,
                start_chainage_m=start_chainage_m,
                distance_m=distance_m,
                duration_s=duration_s,
                cap_mps=cruise_mps,
                initial_speed_mps=initial_speed_mps,
                braking_mps2=braking_mps2,
                limit_braking_mps2=limit_braking_mps2,
                descents=False,
            )
    track = LegTrack(
        track_map,
        model,
        start_chainage_m=start_chainage_m,
        distance_m=distance_m,
        cap_mps=cruise_mps,
        braking_mps2=braking_mps2,
        limit_braking_mps2=limit_braking_mps2,
    )
    return build_profile(track, holding_speed_mps=cruise_mps, initial_speed_mps=initial_speed_mps)
