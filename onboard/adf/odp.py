"""The optimal driving profile (ODP): the reference x_ref(t) = [p_ref(t), v_ref(t)] of seed 000.

Each leg of a journey, from standstill at one stop to standstill at the next, is planned point to
point with a linear segment with parabolic blends (LSPB, DOMAIN.md §5): accelerate at ``a`` for
t_b, cruise at v = a·t_b, brake at ``a`` for t_b, covering Δ in the scheduled time T:

    t_b = (T − √(T² − 4Δ/a)) / 2,   feasible when a ≥ 4Δ/T².

The comfort acceleration is tried first; when its cruise speed would exceed the leg's speed limit
(the lowest MRSP along the leg, and the journey's cap) the cruise speed is set to the limit and
the blends shorten (t_b = T − Δ/v, a = v/t_b), up to the vehicle's acceleration limit. Dwell
times hold the reference at the stop. Positions are distances travelled from the journey's
start; on a ring they map to chainage modulo the line length.

This is the plain LSPB plan, also the energy baseline of the ADF issue.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Protocol

from onboard._exceptions import AdfError
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap

__all__ = [
    "InfeasibleLegError",
    "LegProfile",
    "SPEED_OVERREAD_SHARE",
    "SPEED_UNDERREAD_SHARE",
    "LspbSegment",
    "OdpLeg",
    "OdpPlan",
    "held_under",
    "leg_speed_limit_mps",
    "lspb_segment",
    "plan_legs",
]

COMFORT_ACCELERATION_MPS2 = 0.5
MAX_ACCELERATION_MPS2 = 1.0
LIMIT_SAMPLE_M = 5.0
CAP_MARGIN_MPS = 0.2 * MPS_PER_KMH
"""A plan holds this far under the journey's cap [m/s], which the NMPC holds as a hard ceiling:
a reference on the ceiling leaves it no room to catch up and makes its NLP degenerate."""


SPEED_UNDERREAD_SHARE = 0.006
"""The ADF's speed, the sensor fusion's estimate, comes from the odometer's wheel and may read
low by up to its calibration tolerance (0.6 %, three σ of the diameter error): a plan holds
every ceiling, the MRSP and the journey's cap, that share under it, so that the true speed
stays under the ceiling while the measured one tracks the reference."""


SPEED_OVERREAD_SHARE = 0.02
"""ETCS's speed is the wheels' and reads up to the odometer's diameter tolerance (2 %) high
(``onboard.etcs.odometer``), and its windowed pulse count up to a pulse per window (0.26 km/h:
1.3 % at 20 km/h). Up to a lower limit its target speed monitoring intervenes at any speed it
reads above the limit once the max safe front end is some 20 m short of it, so a lower limit,
and a permitted speed under the MRSP, are held that share under (instead of the ADF's own
under-read share, :data:`SPEED_UNDERREAD_SHARE`, which it covers)."""


def held_under(ceiling_mps: float, margin_mps: float) -> float:
    """The speed [m/s] a plan holds under ``ceiling_mps``: the under-read share of the measured
    speed and the controller's ``margin_mps`` below it."""
    return ceiling_mps * (1.0 - SPEED_UNDERREAD_SHARE) - margin_mps


class InfeasibleLegError(AdfError, ValueError):
    """A leg that no LSPB within the limits can run in its scheduled time."""


@dataclass(frozen=True)
class LspbSegment:
    """Standstill to standstill over ``distance_m`` in ``duration_s``."""

    distance_m: float
    duration_s: float
    acceleration_mps2: float
    blend_s: float

    @property
    def cruise_speed_mps(self) -> float:
        return self.acceleration_mps2 * self.blend_s

    def at(self, t_s: float) -> tuple[float, float]:
        """(distance [m], speed [m/s]) at ``t_s`` from the segment's start, clamped."""
        a, tb, total = self.acceleration_mps2, self.blend_s, self.duration_s
        t = min(max(t_s, 0.0), total)
        if t < tb:
            return 0.5 * a * t * t, a * t
        if t <= total - tb:
            v = a * tb
            return v * (t - tb / 2.0), v
        remaining = total - t
        return self.distance_m - 0.5 * a * remaining * remaining, a * remaining


def lspb_segment(
    distance_m: float,
    duration_s: float,
    *,
    speed_limit_mps: float,
    comfort_acceleration_mps2: float = COMFORT_ACCELERATION_MPS2,
    max_acceleration_mps2: float = MAX_ACCELERATION_MPS2,
) -> LspbSegment:
    """The LSPB covering ``distance_m`` [m] in ``duration_s`` [s] under a speed limit [m/s]."""
    if distance_m <= 0 or duration_s <= 0:
        raise InfeasibleLegError(f"leg of {distance_m} m in {duration_s} s")
    a = max(comfort_acceleration_mps2, 4.0 * distance_m / duration_s**2)
    blend = (duration_s - math.sqrt(max(duration_s**2 - 4.0 * distance_m / a, 0.0))) / 2.0
    if a * blend > speed_limit_mps:
        cruise = speed_limit_mps
        blend = duration_s - distance_m / cruise
        if blend <= 0:
            raise InfeasibleLegError(
                f"{distance_m:.0f} m in {duration_s:.1f} s needs more than {cruise:.2f} m/s"
            )
        a = cruise / blend
    if a > max_acceleration_mps2 * (1 + 1e-9):
        raise InfeasibleLegError(
            f"{distance_m:.0f} m in {duration_s:.1f} s needs {a:.2f} m/s² "
            f"(limit {max_acceleration_mps2} m/s²)"
        )
    return LspbSegment(distance_m, duration_s, a, blend)


class LegProfile(Protocol):
    """A standstill-to-standstill profile of one leg (an LSPB, or an energy-minimised one)."""

    @property
    def distance_m(self) -> float: ...

    @property
    def duration_s(self) -> float: ...

    def at(self, t_s: float) -> tuple[float, float]: ...


@dataclass(frozen=True)
class OdpLeg:
    """A leg in the plan: depart at ``start_s`` from ``start_distance_m``, run to the stop."""

    start_s: float
    start_distance_m: float
    segment: LegProfile

    @property
    def end_s(self) -> float:
        return self.start_s + self.segment.duration_s


class OdpPlan:
    """x_ref(t) from legs and the dwells between them."""

    def __init__(
        self,
        legs: list[OdpLeg],
        *,
        start_chainage_m: float,
        track_map: TrackMap,
        cap_mps: float | None = None,
    ) -> None:
        if not legs:
            raise ValueError("a plan needs at least one leg")
        self.legs = legs
        self.cap_mps = cap_mps
        """The journey's speed cap [m/s], which the controller must respect too."""
        self.start_chainage_m = start_chainage_m
        self.track_map = track_map
        self._starts = [leg.start_s for leg in legs]

    @property
    def end_s(self) -> float:
        return self.legs[-1].end_s

    def reference(self, t_s: float) -> tuple[float, float]:
        """(distance travelled [m], speed [m/s]) of the reference at ``t_s``."""
        index = max(0, bisect.bisect_right(self._starts, t_s) - 1)
        leg = self.legs[index]
        if t_s < leg.start_s:  # before the first departure
            return leg.start_distance_m, 0.0
        distance, speed = leg.segment.at(t_s - leg.start_s)
        return leg.start_distance_m + distance, speed

    def chainage_m(self, distance_m: float) -> float:
        """The chainage of a distance travelled from the start."""
        return self.track_map.normalise(self.start_chainage_m + distance_m)


def plan_legs(
    track_map: TrackMap,
    *,
    start_chainage_m: float,
    stops: list[tuple[float, float, float]],
    cap_mps: float | None = None,
    comfort_acceleration_mps2: float = COMFORT_ACCELERATION_MPS2,
    max_acceleration_mps2: float = MAX_ACCELERATION_MPS2,
) -> OdpPlan:
    """Plan stop to stop.

    Parameters
    ----------
    stops
        For each stop: (distance travelled from the start [m], arrival time [s], departure
        time [s]) with increasing distances and times; the first leg departs at t = 0.
    cap_mps
        Journey speed cap [m/s].
    """
    legs = []
    depart_s, depart_m = 0.0, 0.0
    for index, (distance_m, arrival_s, departure_s) in enumerate(stops):
        length = distance_m - depart_m
        limit = leg_speed_limit_mps(track_map, start_chainage_m + depart_m, length)
        if cap_mps is not None:
            limit = min(limit, held_under(cap_mps, CAP_MARGIN_MPS))
        try:
            segment = lspb_segment(
                length,
                arrival_s - depart_s,
                speed_limit_mps=limit,
                comfort_acceleration_mps2=comfort_acceleration_mps2,
                max_acceleration_mps2=max_acceleration_mps2,
            )
        except InfeasibleLegError as exc:
            raise InfeasibleLegError(f"leg {index}: {exc}") from exc
        legs.append(OdpLeg(depart_s, depart_m, segment))
        depart_s, depart_m = max(departure_s, arrival_s), distance_m
    return OdpPlan(legs, start_chainage_m=start_chainage_m, track_map=track_map, cap_mps=cap_mps)


def leg_speed_limit_mps(track_map: TrackMap, start_m: float, length_m: float) -> float:
    """The lowest MRSP [m/s] over the leg."""
    samples = max(2, math.ceil(length_m / LIMIT_SAMPLE_M) + 1)
    return min(track_map.mrsp_mps(start_m + length_m * k / (samples - 1)) for k in range(samples))
