"""The precision-stop marker reader: the line's stop markers detected under the cab.

A short-range reader under the front end detects each passive tag between the rails (a
:class:`~trackdb.StopMarker`, placed before a stopping point) as it passes over it and reports
the instant it found the tag's centre. Its location error is a few centimetres (metro ATOs'
precision-stop transponders and RFID tag readers locate to a few centimetres at low speed), far
below the BTM's ±1 m; the reading, once per pass and forwards only, is
:class:`~onboard.plant.point_reader.PointReader`'s. A fault option makes chosen markers, or
every marker in chosen time windows, go unread. Values: docs/sensors.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from onboard.plant.point_reader import PointReader
from onboard.plant.readings import MarkerDetection
from onboard.plant.sensors import TimeWindow
from trackdb import StopMarker, TrackMap

__all__ = [
    "MARKER_LOCATION_BOUND_M",
    "MARKER_LOCATION_SIGMA_M",
    "StopMarkerReader",
    "StopMarkerReaderFaults",
]

MARKER_LOCATION_SIGMA_M = 0.02
"""⚠ σ of a marker reading's location error [m]: centimetres, as short-range tag readers give
at the speeds of a final approach (no standard read; a configurable default)."""
MARKER_LOCATION_BOUND_M = 0.06
"""Largest location error [m] (3 σ): errors are drawn normal and redrawn beyond."""


@dataclass(frozen=True, kw_only=True)
class StopMarkerReaderFaults:
    """Readings that do not happen: markers never read (by id), and windows of time [s] in
    which no marker is read."""

    missed_marker_ids: frozenset[str] = frozenset()
    missed_windows: tuple[TimeWindow, ...] = ()

    def missed(self, marker_id: str, time_s: float) -> bool:
        """Whether the reading of marker ``marker_id`` at ``time_s`` [s] is lost."""
        return marker_id in self.missed_marker_ids or any(
            window.start_s <= time_s < window.end_s for window in self.missed_windows
        )


class StopMarkerReader(PointReader[StopMarker, MarkerDetection]):
    """The true front-end position in, :class:`MarkerDetection` out, one plant tick at a time.

    Parameters
    ----------
    track_map : TrackMap
        The line and its stop markers.
    rng : numpy.random.Generator
        Draws each reading's location error.
    location_sigma_m, location_bound_m : float
        σ and bound of the location error [m].
    faults : StopMarkerReaderFaults, optional
        Markers or time windows whose readings are lost.
    """

    def __init__(
        self,
        track_map: TrackMap,
        *,
        rng: np.random.Generator,
        location_sigma_m: float = MARKER_LOCATION_SIGMA_M,
        location_bound_m: float = MARKER_LOCATION_BOUND_M,
        faults: StopMarkerReaderFaults | None = None,
    ) -> None:
        super().__init__(
            track_map,
            rng=rng,
            location_sigma_m=location_sigma_m,
            location_bound_m=location_bound_m,
        )
        self.faults = faults or StopMarkerReaderFaults()

    def points_ahead(self, chainage_m: float, distance_m: float) -> list[tuple[StopMarker, float]]:
        return self.track_map.stop_markers_ahead(chainage_m, distance_m)

    def identity(self, point: StopMarker) -> str:
        return point.id

    def chainage_m(self, point: StopMarker) -> float:
        return point.position_m

    def detection(self, time_s: float, point: StopMarker) -> MarkerDetection:
        return MarkerDetection(time_s=time_s, marker=point)

    def lost(self, point: StopMarker, time_s: float) -> bool:
        return self.faults.missed(point.id, time_s)

    @staticmethod
    def time_of(detection: MarkerDetection) -> float:
        return detection.time_s
