"""TrackMap: the fast, read-only view of a line that the onboard side queries every cycle.

Point queries (gradient, curvature, line speed, MRSP) are pure Python over precomputed lists
with :mod:`bisect`: each costs about a microsecond, which numpy's per-call overhead would
exceed. Numpy serves where a query vectorises: the MRSP sampled at many distances for the
planners, and the global GPS projection (see :mod:`trackdb._geometry`). The step functions, the
MRSP's construction and the walks ahead across a ring's origin are in :mod:`trackdb._profiles`.

Every query takes any chainage [m]: on a ring it wraps at the line's length, on an open line it
is clamped to the line. Distances ahead are counted in the direction of increasing chainage, and
run across the origin of a ring.

The line is read-only; the temporary speed restrictions (TSR) are the one thing that changes at
run time. A TSR with the identity of one in force replaces it, as in SUBSET-026 (3.11.5). The
MRSP (most restrictive speed profile) is rebuilt on each change and swapped in whole, so a
reader never sees a half-built profile.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from trackdb._exceptions import NoGeodeticPolylineError
from trackdb._geometry import GeodeticPolyline, GpsProjection
from trackdb._profiles import (
    Point,
    Profile,
    SpeedSection,
    build_mrsp,
    points_ahead,
    window_sections,
)
from trackdb.schema import (
    BaliseGroup,
    Line,
    StopMarker,
    StoppingPoint,
    TemporarySpeedRestriction,
)

__all__ = ["DEFAULT_MAX_CROSS_TRACK_M", "DEFAULT_WINDOW_M", "SpeedSection", "TrackMap"]

DEFAULT_WINDOW_M = 250.0
"""Half-width [m] of the chainage window of a bounded GPS projection."""
DEFAULT_MAX_CROSS_TRACK_M = 50.0
"""Cross-track distance [m] beyond which a bounded GPS projection is checked globally."""


class TrackMap:
    """The onboard view of a line: profiles, MRSP, stopping points, balise groups, geodesy.

    Parameters
    ----------
    line : Line
        The line; its TSRs are in force from the start.
    """

    def __init__(self, line: Line) -> None:
        self.line = line
        self.version = line.version()
        self._ring = line.ring
        self._length_m = line.length_m
        self._last_m = math.nextafter(line.length_m, 0.0)
        self._gradient = Profile(line.gradient_permille, 0.0)
        self._radius = Profile(line.curve_radius_m, math.inf)
        self._speed = Profile(line.speed_limit_mps, 0.0)
        self._restrictions = {tsr.id: tsr for tsr in line.temporary_speed_restrictions}
        self._mrsp = build_mrsp(line, self._speed, self._restrictions)
        self._stops = sorted(line.stopping_points, key=lambda point: point.position_m)
        self._stop_positions_m = [point.position_m for point in self._stops]
        self._groups = sorted(line.balise_groups, key=lambda group: group.position_m)
        self._group_positions_m = [group.position_m for group in self._groups]
        self._markers = line.stop_markers  # validated in increasing chainage
        self._marker_positions_m = [marker.position_m for marker in self._markers]
        self._polyline = (
            GeodeticPolyline(line.geodetic, length_m=line.length_m, ring=line.ring)
            if line.geodetic
            else None
        )

    @property
    def length_m(self) -> float:
        """The line's length [m]."""
        return self._length_m

    def normalise(self, chainage_m: float) -> float:
        """The chainage on the line [m]: wrapped on a ring, clamped to the ends otherwise."""
        if self._ring:
            wrapped = chainage_m % self._length_m
            # A tiny negative chainage wraps to the length itself, which is the origin.
            return wrapped if wrapped < self._length_m else 0.0
        return min(max(chainage_m, 0.0), self._last_m)

    def gradient_permille(self, chainage_m: float) -> float:
        """Gradient [‰] at the chainage, positive uphill."""
        return self._gradient.at(self.normalise(chainage_m))

    def curve_radius_m(self, chainage_m: float) -> float:
        """Curve radius [m] at the chainage, unsigned; ``inf`` on straight track."""
        return abs(self._radius.at(self.normalise(chainage_m)))

    def curvature_per_m(self, chainage_m: float) -> float:
        """Signed curvature [1/m] at the chainage: positive turning left, 0 on straight track."""
        return 1.0 / self._radius.at(self.normalise(chainage_m))

    def speed_limit_mps(self, chainage_m: float) -> float:
        """Static line speed (SSP) [m/s] at the chainage."""
        return self._speed.at(self.normalise(chainage_m))

    # -- temporary speed restrictions and the MRSP -------------------------------------------

    @property
    def temporary_speed_restrictions(self) -> tuple[TemporarySpeedRestriction, ...]:
        """The TSRs in force, in the order they were put in force."""
        return tuple(self._restrictions.values())

    def add_temporary_speed_restriction(self, restriction: TemporarySpeedRestriction) -> None:
        """Put a TSR in force, replacing any TSR of the same identity.

        Raises
        ------
        ValueError
            If its range ``[start_m, end_m)`` [m] is empty or not on the line.
        """
        if not 0.0 <= restriction.start_m < restriction.end_m <= self._length_m:
            raise ValueError(
                f"TSR {restriction.id!r}: {restriction.start_m}..{restriction.end_m} m is not a"
                f" range on line {self.line.id!r} (0..{self._length_m} m)"
            )
        restrictions = {**self._restrictions, restriction.id: restriction}
        self._mrsp = build_mrsp(self.line, self._speed, restrictions)
        self._restrictions = restrictions

    def revoke_temporary_speed_restriction(self, restriction_id: str) -> bool:
        """Revoke the TSR of that identity; False if none was in force."""
        if restriction_id not in self._restrictions:
            return False
        restrictions = dict(self._restrictions)
        del restrictions[restriction_id]
        self._mrsp = build_mrsp(self.line, self._speed, restrictions)
        self._restrictions = restrictions
        return True

    def mrsp_mps(self, chainage_m: float) -> float:
        """MRSP [m/s] at the chainage: the lowest of the SSP and the TSRs in force there."""
        steps = self._mrsp
        return steps.values[bisect.bisect_right(steps.starts, self.normalise(chainage_m)) - 1]

    def mrsp_window(self, start_m: float, length_m: float) -> list[SpeedSection]:
        """The MRSP over a window ahead, as sections of distance travelled from ``start_m``.

        Parameters
        ----------
        start_m : float
            Chainage [m] the window starts at; clamped to ``[0, length]`` on an open line.
        length_m : float
            Length [m] of the window, at least 0; on a ring it may exceed the ring's length.

        Returns
        -------
        list of SpeedSection
            Contiguous sections from distance 0, merged where the speed [m/s] is the same. They
            cover ``length_m``, except that on an open line they stop at the line's end (empty
            at the end itself): there is no track, hence no speed, beyond it.
        """
        if not (math.isfinite(length_m) and length_m >= 0.0):
            raise ValueError(f"window length {length_m} m is not a finite length")
        if self._ring:
            origin_m = self.normalise(start_m)
            limit_m = float(length_m)
        else:
            origin_m = min(max(start_m, 0.0), self._length_m)
            limit_m = min(length_m, self._length_m - origin_m)
        return window_sections(self._mrsp, origin_m, limit_m, self._length_m)

    def mrsp_ahead_mps(self, start_m: float, distances_m: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """MRSP [m/s] at distances [m] from ``start_m``, vectorised for planners.

        Parameters
        ----------
        start_m : float
            Chainage [m] the distances are counted from.
        distances_m : array_like, shape (n,) or any shape
            Distances [m] ahead (negative: behind); the positions wrap or clamp as in
            :meth:`normalise`.

        Returns
        -------
        numpy.ndarray, the shape of ``distances_m``
            The MRSP [m/s] at each ``start_m + distances_m``, as :meth:`mrsp_mps` gives it.
        """
        positions_m = start_m + np.asarray(distances_m, dtype=np.float64)
        if self._ring:
            positions_m = np.mod(positions_m, self._length_m)
            # As in normalise: a tiny negative position wraps to the length, the origin.
            positions_m = np.where(positions_m < self._length_m, positions_m, 0.0)
        else:
            positions_m = np.clip(positions_m, 0.0, self._last_m)
        steps = self._mrsp
        indices = np.searchsorted(steps.starts_array, positions_m, side="right") - 1
        speeds: npt.NDArray[np.float64] = steps.values_array[indices]
        return speeds

    # -- points along the line --------------------------------------------------------------

    def next_stopping_point(
        self, chainage_m: float, *, max_distance_m: float | None = None
    ) -> tuple[StoppingPoint, float] | None:
        """The first stopping point at or ahead of the chainage, and its distance [m].

        A point at the chainage itself is at distance 0. On a ring the search runs across the
        origin; on an open line it ends at the line's end. None if no point lies ahead within
        ``max_distance_m`` [m] (no limit when None).
        """
        positions_m = self._stop_positions_m
        if not positions_m:
            return None
        position_m = self.normalise(chainage_m)
        index = bisect.bisect_left(positions_m, position_m)
        if index < len(positions_m):
            distance_m = positions_m[index] - position_m
        elif self._ring:
            index, distance_m = 0, positions_m[0] + self._length_m - position_m
        else:
            return None
        if max_distance_m is not None and distance_m > max_distance_m:
            return None
        return self._stops[index], distance_m

    def distance_beyond_balise_group_m(self, chainage_m: float) -> float | None:
        """How far [m] the chainage lies beyond the last balise group before it (or at it): the
        distance an odometer has run since its last reset there. On a ring the last group of
        the previous lap counts; None before the first group of a line, or with no groups."""
        positions_m = self._group_positions_m
        if not positions_m:
            return None
        position_m = self.normalise(chainage_m)
        index = bisect.bisect_right(positions_m, position_m) - 1
        if index >= 0:
            return position_m - positions_m[index]
        if self._ring:
            return position_m + self._length_m - positions_m[-1]
        return None

    def balise_groups_ahead(
        self, chainage_m: float, distance_m: float
    ) -> list[tuple[BaliseGroup, float]]:
        """The balise groups from the chainage to ``distance_m`` [m] ahead, both included.

        Returns
        -------
        list of (BaliseGroup, float)
            Each group with its distance [m] ahead, in the order the train meets them. On a
            ring a window longer than the ring meets a group once per lap.
        """
        return self._ahead(self._groups, self._group_positions_m, chainage_m, distance_m)

    def stop_markers_ahead(
        self, chainage_m: float, distance_m: float
    ) -> list[tuple[StopMarker, float]]:
        """The precision-stop markers ahead, as :meth:`balise_groups_ahead` gives groups."""
        return self._ahead(self._markers, self._marker_positions_m, chainage_m, distance_m)

    def _ahead(
        self,
        points: Sequence[Point],
        positions_m: list[float],
        chainage_m: float,
        distance_m: float,
    ) -> list[tuple[Point, float]]:
        ring_length_m = self._length_m if self._ring else None
        at_m = self.normalise(chainage_m)
        return points_ahead(points, positions_m, at_m, distance_m, ring_length_m=ring_length_m)

    # -- geodesy ------------------------------------------------------------------------------

    def _geodetic(self) -> GeodeticPolyline:
        if self._polyline is None:
            raise NoGeodeticPolylineError(f"line {self.line.id!r} has no geodetic polyline")
        return self._polyline

    def altitude_m(self, chainage_m: float) -> float:
        """Altitude [m] at the chainage, interpolated along the geodetic polyline.

        Raises
        ------
        NoGeodeticPolylineError
            If the line has no geodetic polyline.
        """
        return self._geodetic().altitude_m(self.normalise(chainage_m))

    def geodetic_at(self, chainage_m: float) -> tuple[float, float, float]:
        """Latitude [deg], longitude [deg] and altitude [m] at the chainage (WGS 84).

        Raises
        ------
        NoGeodeticPolylineError
            If the line has no geodetic polyline.
        """
        return self._geodetic().at(self.normalise(chainage_m))

    def project(
        self,
        latitude_deg: float,
        longitude_deg: float,
        *,
        near_m: float | None = None,
        window_m: float = DEFAULT_WINDOW_M,
        max_cross_track_m: float = DEFAULT_MAX_CROSS_TRACK_M,
    ) -> GpsProjection:
        """Project a GPS fix onto the track: the chainage of the nearest point, and the offset.

        Parameters
        ----------
        latitude_deg, longitude_deg : float
            The fix [deg] (WGS 84).
        near_m : float, optional
            The last chainage estimate [m]. Given, only the polyline segments within
            ``near_m ± window_m`` are searched, wrapping on a ring; the whole polyline is
            searched if that search's best point lies at an edge of the window or further than
            ``max_cross_track_m`` from the fix. Without it the whole polyline is searched.
        window_m : float
            Half-width [m] of the bounded search's window.
        max_cross_track_m : float
            Distance [m] from the track beyond which a bounded answer is not trusted.

        Returns
        -------
        GpsProjection
            Chainage [m] on the line, signed cross-track distance [m] (positive to the left of
            increasing chainage), and whether the bounded search gave the answer.

        Raises
        ------
        ValueError
            If the fix is not finite.
        NoGeodeticPolylineError
            If the line has no geodetic polyline.
        """
        if not (math.isfinite(latitude_deg) and math.isfinite(longitude_deg)):
            raise ValueError(f"GPS fix ({latitude_deg}, {longitude_deg}) is not finite")
        return self._geodetic().project(
            latitude_deg,
            longitude_deg,
            near_m=None if near_m is None else self.normalise(near_m),
            window_m=window_m,
            max_cross_track_m=max_cross_track_m,
        )
