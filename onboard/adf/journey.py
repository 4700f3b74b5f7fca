"""From a journey profile to the ODP: stops as distances ahead of the train, times from the start.

A journey profile locates its timing points (TPs) by chainage and times them from the journey's
start; the ADF plans from where the train stands when the journey starts, so each stopping TP
becomes a distance travelled (forward along the line: modulo the length on a ring) with its
arrival and departure times. A passing TP becomes a time constraint inside its leg: the energy
plan passes it at its arrival time (``onboard.adf.odp_journey``); the plain LSPB plan goes stop
to stop. TPs to be skipped are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

from onboard.adf.odp import InfeasibleLegError, OdpPlan, plan_legs
from onboard.adf.odp_journey import LegFallback, PassingMiss, PassingPoint, plan_energy_journey
from onboard.plant.point_mass import PointMassParameters
from protocol import messages as m
from trackdb import TrackMap

__all__ = ["JourneyPlan", "JourneyStop", "plan_journey"]

MIN_LEG_M = 1.0


@dataclass(frozen=True)
class JourneyStop:
    """A stopping TP as the ADF sees it."""

    timing_point_id: str
    distance_m: float
    """Distance travelled from the journey's start [m]."""
    arrival_s: float
    departure_s: float
    end_of_journey: bool


@dataclass(frozen=True)
class JourneyPlan:
    journey_id: str
    version: int
    start_chainage_m: float
    stops: tuple[JourneyStop, ...]
    plan: OdpPlan
    legs_kept_plain: int
    """Legs that kept the plain LSPB (no energy-minimised profile arrives on time)."""
    passing: tuple[PassingPoint, ...] = ()
    """The passing TPs, as time constraints of the energy plan."""
    fallbacks: tuple[LegFallback, ...] = ()
    """Each leg that kept the plain LSPB, with the reason (energy plans only)."""
    passing_missed: tuple[PassingMiss, ...] = ()
    """Passing TPs whose time no profile of their leg meets (the leg ignores them)."""


def plan_journey(
    track_map: TrackMap,
    model: PointMassParameters,
    profile: m.JourneyProfile,
    *,
    start_chainage_m: float,
    energy: bool = True,
) -> JourneyPlan:
    """The ODP for a journey starting now at ``start_chainage_m``.

    Raises
    ------
    InfeasibleLegError
        When a stop lies behind the train on an open line, two stops coincide, or a leg cannot
        be run in its time under the limits; the message names the timing point.
    """
    stops, passing = _timing_points(track_map, profile, start_chainage_m)
    legs = [(stop.distance_m, stop.arrival_s, stop.departure_s) for stop in stops]
    cap = profile.max_speed_mps
    fallbacks: tuple[LegFallback, ...] = ()
    missed: tuple[PassingMiss, ...] = ()
    try:
        if energy:
            planned = plan_energy_journey(
                track_map,
                model,
                start_chainage_m=start_chainage_m,
                stops=legs,
                passing=passing,
                cap_mps=cap,
            )
            plan, fallbacks, missed = planned.plan, planned.fallbacks, planned.passing_missed
            kept = planned.kept_plain
        else:
            plan = plan_legs(track_map, start_chainage_m=start_chainage_m, stops=legs, cap_mps=cap)
            kept = len(legs)
    except InfeasibleLegError as exc:
        raise InfeasibleLegError(f"journey {profile.journey_id}: {exc}") from exc
    return JourneyPlan(
        profile.journey_id,
        profile.version,
        start_chainage_m,
        tuple(stops),
        plan,
        kept,
        tuple(passing),
        fallbacks,
        missed,
    )


def _timing_points(
    track_map: TrackMap, profile: m.JourneyProfile, start_chainage_m: float
) -> tuple[list[JourneyStop], list[PassingPoint]]:
    """The stopping TPs and the passing ones, located as distances travelled.

    Raises
    ------
    InfeasibleLegError
        As :func:`plan_journey`.
    """
    stops: list[JourneyStop] = []
    passing: list[PassingPoint] = []
    travelled = 0.0
    here = start_chainage_m
    for point in profile.timing_points:
        if point.kind is m.TimingPointKind.SKIP:
            continue
        ahead = _forward_distance_m(track_map, here, point.position_m)
        if ahead < MIN_LEG_M:
            raise InfeasibleLegError(
                f"timing point {point.id} is not ahead of the train ({ahead:.1f} m)"
            )
        travelled += ahead
        here = point.position_m
        if point.kind is m.TimingPointKind.PASSING:
            passing.append(PassingPoint(point.id, travelled, point.arrival_time_s))
            continue
        departure = (
            point.arrival_time_s
            if point.departure_time_s is None
            else (max(point.departure_time_s, point.arrival_time_s + point.minimum_dwell_s))
        )
        stops.append(
            JourneyStop(point.id, travelled, point.arrival_time_s, departure, point.end_of_journey)
        )
    if not stops:
        raise InfeasibleLegError("the journey has no stopping timing point")
    return stops, passing


def _forward_distance_m(track_map: TrackMap, from_m: float, to_m: float) -> float:
    if track_map.line.ring:
        return (to_m - from_m) % track_map.length_m
    return to_m - from_m
