"""A reader of points on the track, passed over by the front end: balise groups, stop markers.

A reader under the vehicle detects a point of the track (a balise group, a precision-stop
marker) as the antenna passes over it and reports the instant it located the point's centre.
That location has an error, drawn from the seed for each pass and bounded: the front end was
then near the point, not exactly on it. :class:`PointReader` follows the true front-end position
tick by tick and reports a detection when the front passes the point's location plus that
pass's error; the detection's instant is interpolated within the tick.

Points are read in the direction of increasing chainage only, and once per pass: the reader
follows the furthest position reached, so a train rolling back and on again over a point does
not read it twice. On a ring each lap is a new pass. Subclasses say which points the track has
ahead, their identity and location, what a detection is, and which readings a fault loses.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Hashable
from typing import Generic, TypeVar

import numpy as np

from trackdb import TrackMap

__all__ = ["LOOK_AHEAD_M", "PointReader"]

Point = TypeVar("Point")
Detection = TypeVar("Detection")
Pass = tuple[Hashable, int]
"""A pass over a point: the point's identity and the lap."""
LOOK_AHEAD_M = 100.0
"""How far beyond its window a reader looks for the next point [m]: while the front has not
come within reach of it, a tick asks the track for nothing (about ten seconds of ticks at
40 km/h)."""


class PointReader(ABC, Generic[Point, Detection]):
    """The true front-end position in, detections out, one plant tick at a time.

    Parameters
    ----------
    track_map : TrackMap
        The line and its points.
    rng : numpy.random.Generator
        Draws each pass's location error.
    location_sigma_m : float
        σ of the location error [m]; 0 makes readings exact.
    location_bound_m : float
        Largest location error [m], at least ``location_sigma_m``: errors are drawn normal and
        redrawn beyond it.

    Attributes
    ----------
    read, missed : int
        Readings reported, and readings lost to a fault.
    last_errors_m : dict
        For each point's identity, the location error [m] of its last reading (reported or
        lost): where the front end was, beyond the point, at the detection's instant.
    """

    def __init__(
        self,
        track_map: TrackMap,
        *,
        rng: np.random.Generator,
        location_sigma_m: float,
        location_bound_m: float,
    ) -> None:
        if location_sigma_m < 0.0 or location_bound_m < location_sigma_m:
            raise ValueError("need 0 <= location_sigma_m <= location_bound_m")
        self.track_map = track_map
        self.rng = rng
        self.location_sigma_m = location_sigma_m
        self.location_bound_m = location_bound_m
        self.read = 0
        self.missed = 0
        self.last_errors_m: dict[Hashable, float] = {}
        self._time_s = 0.0
        self._position_m: float | None = None
        self._furthest_m = 0.0
        self._errors_m: dict[Pass, float] = {}
        """The drawn error of each pass not yet read."""
        self._done: set[Pass] = set()
        """The passes read, lost, or behind the start, still near enough to be seen again."""
        self._clear_until_m = -math.inf
        """While the front plus the bound stays below this [m], no point is within reach: the
        last window held none, and the nearest point beyond it lies here (a step then does
        nothing but move the furthest position)."""

    # -- what a subclass says ----------------------------------------------------------------------

    @abstractmethod
    def points_ahead(self, chainage_m: float, distance_m: float) -> list[tuple[Point, float]]:
        """The points from ``chainage_m`` to ``distance_m`` [m] ahead, with their distance."""

    @abstractmethod
    def identity(self, point: Point) -> Hashable:
        """The point's identity (NID_BG, a marker's id)."""

    @abstractmethod
    def chainage_m(self, point: Point) -> float:
        """The point's chainage [m]."""

    @abstractmethod
    def detection(self, time_s: float, point: Point) -> Detection:
        """What the reader reports of ``point`` located at ``time_s`` [s]."""

    @abstractmethod
    def lost(self, point: Point, time_s: float) -> bool:
        """Whether a fault loses the reading of ``point`` at ``time_s`` [s]."""

    @staticmethod
    @abstractmethod
    def time_of(detection: Detection) -> float:
        """A detection's instant [s]."""

    # -- stepping ----------------------------------------------------------------------------------

    def step(self, time_s: float, front_position_m: float) -> list[Detection]:
        """The points read since the last step.

        Parameters
        ----------
        time_s : float
            The tick's instant [s].
        front_position_m : float
            The true front-end position [m], unwrapped on a ring (it keeps counting past the
            origin). The first step only places the reader: a point whose reading point lies
            at or behind it is not read.

        Returns
        -------
        list
            In the order met, each at the instant [s] interpolated within the tick at which
            the front passed the point's location plus the reading's error.
        """
        last_time_s, last_m = self._time_s, self._position_m
        self._time_s, self._position_m = time_s, front_position_m
        if last_m is None:
            self._furthest_m = front_position_m
            for key, _, location_m in self._passes(front_position_m):
                if location_m + self._error_m(key) <= front_position_m:
                    self._done.add(key)
                    del self._errors_m[key]
            return []
        furthest_m = self._furthest_m
        if front_position_m <= furthest_m:
            return []
        if front_position_m + self.location_bound_m < self._clear_until_m:
            # No point lies from the furthest position less the bound to the front plus the
            # bound (the last look ahead found none before _clear_until_m): nothing to read,
            # and no pass to forget.
            self._furthest_m = front_position_m
            return []
        detections: list[Detection] = []
        for key, point, location_m in self._passes(front_position_m):
            if key in self._done:
                continue
            error_m = self._error_m(key)
            reading_m = location_m + error_m
            if reading_m > front_position_m:
                continue
            self._done.add(key)
            del self._errors_m[key]
            # The front moved linearly from last_m over the tick, and the reading point lies
            # beyond furthest_m ≥ last_m: the fraction is within (0, 1].
            fraction = (reading_m - last_m) / (front_position_m - last_m)
            detection_s = last_time_s + fraction * (time_s - last_time_s)
            self.last_errors_m[self.identity(point)] = error_m
            if self.lost(point, detection_s):
                self.missed += 1
                continue
            self.read += 1
            detections.append(self.detection(detection_s, point))
        self._furthest_m = front_position_m
        detections.sort(key=self.time_of)
        return detections

    def _passes(self, front_m: float) -> list[tuple[Pass, Point, float]]:
        """The passes over a point whose reading point may lie between the furthest position
        and ``front_m`` [m]: (identity, lap), the point, its unwrapped location [m]. Passes
        left behind for good are forgotten."""
        bound_m = self.location_bound_m
        start_m = self._furthest_m - bound_m
        window_m = front_m + bound_m - start_m
        ahead = self.points_ahead(start_m, window_m + LOOK_AHEAD_M)
        length_m = self.track_map.length_m
        ring = self.track_map.line.ring
        passes: list[tuple[Pass, Point, float]] = []
        clear_until_m = start_m + window_m + LOOK_AHEAD_M
        for point, distance_m in ahead:
            if distance_m > window_m:  # the nearest point beyond the window
                clear_until_m = start_m + distance_m
                break
            location_m = start_m + distance_m
            lap = round((location_m - self.chainage_m(point)) / length_m) if ring else 0
            passes.append(((self.identity(point), lap), point, location_m))
        self._clear_until_m = -math.inf if passes else clear_until_m
        # A pass before the window's start can never come back into it (the start only moves
        # forward); its error was used.
        keys = {key for key, _, _ in passes}
        self._done &= keys
        return passes

    def _error_m(self, key: Pass) -> float:
        """The location error [m] of a pass, drawn when first asked for."""
        error_m = self._errors_m.get(key)
        if error_m is None:
            error_m = self._errors_m[key] = self._draw_error()
        return error_m

    def _draw_error(self) -> float:
        sigma, bound = self.location_sigma_m, self.location_bound_m
        if sigma <= 0.0:
            return 0.0
        while True:
            error = float(self.rng.normal(0.0, sigma))
            if abs(error) <= bound:
                return error
