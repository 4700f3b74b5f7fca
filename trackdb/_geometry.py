"""The geodetic polyline of a line, as TrackMap uses it: interpolation and GPS projection.

Positions along the polyline are interpolated linearly between its points, in latitude,
longitude and altitude. For projection the points are converted once to a local east/north plane
(:func:`~trackdb.builder.geodetic_to_enu`, origin at the first point); a fix is converted the
same way and projected onto the segments in that plane. Since the conversion is affine in
latitude and longitude, a point interpolated by :meth:`GeodeticPolyline.at` projects back onto
the same chainage up to rounding.

Two searches: a bounded one, in pure Python, over the segments whose chainage lies within a
window around the last estimate (cheap per call, and immune to a nearer but wrong stretch of
track further along the line); and a global one, vectorised with numpy over every segment.
The bounded answer is distrusted, and the global search decides, when its best point lies at an
edge of the window (the fix may be further along) or further from the track than
``max_cross_track_m`` (the estimate may be on the wrong stretch altogether).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from trackdb._exceptions import NoGeodeticPolylineError
from trackdb.builder import geodetic_to_enu
from trackdb.schema import GeoPoint

__all__ = ["GeodeticPolyline", "GpsProjection"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class GpsProjection:
    """A GPS fix projected onto the track.

    Attributes
    ----------
    chainage_m : float
        Chainage [m] of the nearest point of the track, on the line (wrapped on a ring).
    cross_track_m : float
        Distance [m] from that point to the fix, positive when the fix lies to the left of the
        direction of increasing chainage.
    bounded : bool
        True when the bounded search around the estimate gave the answer; False when the global
        search did (no estimate given, or the bounded answer was distrusted).
    """

    chainage_m: float
    cross_track_m: float
    bounded: bool


class GeodeticPolyline:
    """Interpolation and projection over a line's geodetic polyline.

    Parameters
    ----------
    points : tuple of GeoPoint
        At least two points at strictly increasing chainage [m], as :class:`~trackdb.schema.Line`
        validates them.
    length_m : float
        The line's length [m], where the polyline ends.
    ring : bool
        Whether the line is a ring: the last point closes onto the first, and chainage wraps at
        ``length_m``.
    """

    def __init__(self, points: tuple[GeoPoint, ...], *, length_m: float, ring: bool) -> None:
        if len(points) < 2:
            raise NoGeodeticPolylineError("a geodetic polyline needs at least two points")
        self.ring = ring
        self._chainages_m = [point.chainage_m for point in points]
        self._latitudes_deg = [point.latitude_deg for point in points]
        self._longitudes_deg = [point.longitude_deg for point in points]
        self._altitudes_m = [point.altitude_m for point in points]
        self.length_m = length_m
        self._origin = (points[0].latitude_deg, points[0].longitude_deg)
        east_north = [
            geodetic_to_enu(point.latitude_deg, point.longitude_deg, *self._origin)
            for point in points
        ]
        east = [e for e, _ in east_north]
        north = [n for _, n in east_north]
        # Per segment: start, direction vector, 1/|direction|² and the chainage span.
        self._east_m = east[:-1]
        self._north_m = north[:-1]
        self._delta_east_m = [b - a for a, b in zip(east, east[1:], strict=False)]
        self._delta_north_m = [b - a for a, b in zip(north, north[1:], strict=False)]
        self._inverse_square_m2 = [
            1.0 / (de * de + dn * dn) if de or dn else 0.0
            for de, dn in zip(self._delta_east_m, self._delta_north_m, strict=True)
        ]
        self._delta_chainage_m = [
            b - a for a, b in zip(self._chainages_m, self._chainages_m[1:], strict=False)
        ]
        self._arrays = tuple(
            np.asarray(values, dtype=np.float64)
            for values in (
                self._east_m,
                self._north_m,
                self._delta_east_m,
                self._delta_north_m,
                self._inverse_square_m2,
            )
        )

    @property
    def segment_count(self) -> int:
        """Number of segments of the polyline."""
        return len(self._delta_chainage_m)

    def _segment(self, chainage_m: float) -> int:
        index = bisect.bisect_right(self._chainages_m, chainage_m) - 1
        return min(max(index, 0), len(self._delta_chainage_m) - 1)

    def at(self, chainage_m: float) -> tuple[float, float, float]:
        """Latitude [deg], longitude [deg] and altitude [m] at a chainage on the line [m]."""
        index = self._segment(chainage_m)
        fraction = (chainage_m - self._chainages_m[index]) / self._delta_chainage_m[index]
        latitudes, longitudes, altitudes = (
            self._latitudes_deg,
            self._longitudes_deg,
            self._altitudes_m,
        )
        return (
            latitudes[index] + fraction * (latitudes[index + 1] - latitudes[index]),
            longitudes[index] + fraction * (longitudes[index + 1] - longitudes[index]),
            altitudes[index] + fraction * (altitudes[index + 1] - altitudes[index]),
        )

    def altitude_m(self, chainage_m: float) -> float:
        """Altitude [m] at a chainage on the line [m]."""
        index = self._segment(chainage_m)
        fraction = (chainage_m - self._chainages_m[index]) / self._delta_chainage_m[index]
        altitudes = self._altitudes_m
        return altitudes[index] + fraction * (altitudes[index + 1] - altitudes[index])

    def project(
        self,
        latitude_deg: float,
        longitude_deg: float,
        *,
        near_m: float | None,
        window_m: float,
        max_cross_track_m: float,
    ) -> GpsProjection:
        """Project a fix onto the track; see :meth:`trackdb.track_map.TrackMap.project`."""
        east_m, north_m = geodetic_to_enu(latitude_deg, longitude_deg, *self._origin)
        if near_m is not None:
            first, last, edges = self._window(near_m, window_m)
            index, along, distance_m, at_edge = self._search_window(
                east_m, north_m, first, last, edges
            )
            if not at_edge and distance_m <= max_cross_track_m:
                return self._result(index, along, east_m, north_m, bounded=True)
        index, along = self._search_all(east_m, north_m)
        return self._result(index, along, east_m, north_m, bounded=False)

    def _window(self, near_m: float, window_m: float) -> tuple[int, int, tuple[bool, bool]]:
        """Segments ``first..last`` (unwrapped on a ring) covering ``near_m ± window_m``, and
        whether each end of that range is a window edge rather than an end of the line."""
        count = self.segment_count
        if not self.ring:
            first = self._segment(max(near_m - window_m, 0.0))
            last = self._segment(min(near_m + window_m, self.length_m))
            return first, last, (first > 0, last < count - 1)
        if 2.0 * window_m >= self.length_m:
            return 0, count - 1, (False, False)
        first = self._unwrapped_segment(near_m - window_m)
        last = self._unwrapped_segment(near_m + window_m)
        if last - first + 1 >= count:
            return first, first + count - 1, (False, False)
        return first, last, (True, True)

    def _unwrapped_segment(self, chainage_m: float) -> int:
        laps = math.floor(chainage_m / self.length_m)
        local_m = chainage_m - laps * self.length_m
        return laps * self.segment_count + self._segment(local_m)

    def _search_window(
        self, east_m: float, north_m: float, first: int, last: int, edges: tuple[bool, bool]
    ) -> tuple[int, float, float, bool]:
        """Best segment, position along it (0..1), distance [m] and whether it is at an edge."""
        east, north = self._east_m, self._north_m
        delta_east, delta_north = self._delta_east_m, self._delta_north_m
        inverse_square = self._inverse_square_m2
        count = self.segment_count
        best_square_m2 = math.inf
        best_index, best_along, best_step = first % count, 0.0, first
        for step in range(first, last + 1):
            index = step % count
            offset_east = east_m - east[index]
            offset_north = north_m - north[index]
            along = (
                offset_east * delta_east[index] + offset_north * delta_north[index]
            ) * inverse_square[index]
            if along < 0.0:
                along = 0.0
            elif along > 1.0:
                along = 1.0
            miss_east = offset_east - along * delta_east[index]
            miss_north = offset_north - along * delta_north[index]
            square_m2 = miss_east * miss_east + miss_north * miss_north
            if square_m2 < best_square_m2:
                best_square_m2, best_index, best_along, best_step = square_m2, index, along, step
        at_edge = (edges[0] and best_step == first and best_along <= 0.0) or (
            edges[1] and best_step == last and best_along >= 1.0
        )
        return best_index, best_along, math.sqrt(best_square_m2), at_edge

    def _search_all(self, east_m: float, north_m: float) -> tuple[int, float]:
        """Best segment and position along it (0..1) over the whole polyline, vectorised."""
        east, north, delta_east, delta_north, inverse_square = self._arrays
        offset_east = east_m - east
        offset_north = north_m - north
        along = np.clip(
            (offset_east * delta_east + offset_north * delta_north) * inverse_square, 0.0, 1.0
        )
        miss_east = offset_east - along * delta_east
        miss_north = offset_north - along * delta_north
        index = int(np.argmin(miss_east * miss_east + miss_north * miss_north))
        return index, float(along[index])

    def _result(
        self, index: int, along: float, east_m: float, north_m: float, *, bounded: bool
    ) -> GpsProjection:
        offset_east = east_m - self._east_m[index]
        offset_north = north_m - self._north_m[index]
        delta_east, delta_north = self._delta_east_m[index], self._delta_north_m[index]
        distance_m = math.hypot(
            offset_east - along * delta_east, offset_north - along * delta_north
        )
        left = delta_east * offset_north - delta_north * offset_east
        chainage_m = self._chainages_m[index] + along * self._delta_chainage_m[index]
        if chainage_m >= self.length_m:  # the end of the last segment
            chainage_m = 0.0 if self.ring else math.nextafter(self.length_m, 0.0)
        return GpsProjection(
            chainage_m=chainage_m, cross_track_m=math.copysign(distance_m, left), bounded=bounded
        )
