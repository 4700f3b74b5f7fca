"""From a journey profile to the ODP: stops as distances ahead of the train, times from the start.

A journey profile locates its timing points (TPs) by chainage and times them from the journey's
start; the ADF plans from where the train stands when the journey starts, so each stopping TP
becomes a distance travelled (forward along the line: modulo the length on a ring) with its
arrival and departure times. Passing TPs are not planned for (the ADF plans stop to stop; a
passing time is a check for the report, not a constraint of the plan), and TPs to be skipped
are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

from onboard.adf.odp import InfeasibleLegError, OdpPlan, plan_legs
from onboard.adf.odp_energy import plan_energy_legs
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
    stops: list[JourneyStop] = []
    travelled = 0.0
    here = start_chainage_m
    for point in profile.timing_points:
        if point.kind is not m.TimingPointKind.STOPPING:
            continue
        ahead = _forward_distance_m(track_map, here, point.position_m)
        if ahead < MIN_LEG_M:
            raise InfeasibleLegError(
                f"timing point {point.id} is not ahead of the train ({ahead:.1f} m)"
            )
        travelled += ahead
        here = point.position_m
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
    legs = [(stop.distance_m, stop.arrival_s, stop.departure_s) for stop in stops]
    cap = profile.max_speed_mps
    try:
        if energy:
            plan, kept = plan_energy_legs(
                track_map, model, start_chainage_m=start_chainage_m, stops=legs, cap_mps=cap
            )
        else:
            plan = plan_legs(track_map, start_chainage_m=start_chainage_m, stops=legs, cap_mps=cap)
            kept = len(legs)
    except InfeasibleLegError as exc:
        raise InfeasibleLegError(f"journey {profile.journey_id}: {exc}") from exc
    return JourneyPlan(
        profile.journey_id, profile.version, start_chainage_m, tuple(stops), plan, kept
    )


def _forward_distance_m(track_map: TrackMap, from_m: float, to_m: float) -> float:
    if track_map.line.ring:
        return (to_m - from_m) % track_map.length_m
    return to_m - from_m
