"""Journeys of the tests on the Bologna ring: stops at its platforms under a 40 km/h cap."""

from __future__ import annotations

from protocol.units import MPS_PER_KMH
from trackdb.journey import Journey, JourneyTimingPoint

RING = "bologna-ring"


def ring_journey(
    journey_id: str, start_m: float, stops: list[tuple[str, float, float | None]]
) -> Journey:
    """A journey from ``start_m`` through ``stops``: (platform, arrival, departure, or None for
    the end of the journey) [s from its start]."""
    return Journey(
        id=journey_id,
        line_id=RING,
        start_position_m=start_m,
        max_speed_mps=40.0 * MPS_PER_KMH,
        timing_points=tuple(
            JourneyTimingPoint(
                id=platform,
                stopping_point_id=platform,
                arrival_time_s=arrival,
                departure_time_s=departure,
                end_of_journey=departure is None,
            )
            for platform, arrival, departure in stops
        ),
    )
