"""The balise transmission module (BTM): balise groups read under the antenna, as the train does.

The BTM reads a group's telegram as the antenna passes over it and reports the instant it
located the group's centre. That location has an error (SUBSET-036 allows ±1 m): the front end
was then near the group, not exactly on it. :class:`BaliseReader` follows the true front-end
position tick by tick and reports a :class:`~onboard.plant.readings.BaliseDetection` when the
front passes a group's location plus that reading's error, drawn from the seed; the detection's
instant is interpolated within the tick. A fault option makes chosen groups, or every group in
chosen time windows, go unread (the scenario ``balise-missed``).

Groups are read in the direction of increasing chainage only, and once per pass: the reader
follows the furthest position reached, so a train rolling back and on again over a group does
not read it twice. On a ring each lap is a new pass. Error sources and values: docs/sensors.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from onboard.plant.readings import BaliseDetection
from onboard.plant.sensors import TimeWindow
from trackdb import BaliseGroup, TrackMap

__all__ = [
    "LOCATION_BOUND_M",
    "LOCATION_SIGMA_M",
    "BaliseReader",
    "BaliseReaderFaults",
]

LOCATION_SIGMA_M = 0.4
"""σ of a reading's location error [m]: well inside SUBSET-036's ±1 m."""
LOCATION_BOUND_M = 1.0
"""Largest location error [m] (SUBSET-036's ±1 m): errors are drawn normal and redrawn beyond."""


@dataclass(frozen=True, kw_only=True)
class BaliseReaderFaults:
    """Readings that do not happen: groups never read (by NID_BG), and windows of time [s] in
    which no group is read."""

    missed_group_ids: frozenset[int] = frozenset()
    missed_windows: tuple[TimeWindow, ...] = ()

    def missed(self, group_id: int, time_s: float) -> bool:
        """Whether the reading of group ``group_id`` at ``time_s`` [s] is lost."""
        return group_id in self.missed_group_ids or any(
            window.start_s <= time_s < window.end_s for window in self.missed_windows
        )


class BaliseReader:
    """The true front-end position in, :class:`BaliseDetection` out, one plant tick at a time.

    Parameters
    ----------
    track_map : TrackMap
        The line and its balise groups.
    rng : numpy.random.Generator
        Draws each reading's location error.
    location_sigma_m : float
        σ of the location error [m]; 0 makes readings exact.
    location_bound_m : float
        Largest location error [m], at least ``location_sigma_m``.
    faults : BaliseReaderFaults, optional
        Groups or time windows whose readings are lost.

    Attributes
    ----------
    read, missed : int
        Readings reported, and readings lost to a fault.
    last_errors_m : dict of int to float
        For each group id, the location error [m] of its last reading (reported or lost):
        where the front end was, beyond the group, at the detection's instant.
    """

    def __init__(
        self,
        track_map: TrackMap,
        *,
        rng: np.random.Generator,
        location_sigma_m: float = LOCATION_SIGMA_M,
        location_bound_m: float = LOCATION_BOUND_M,
        faults: BaliseReaderFaults | None = None,
    ) -> None:
        if location_sigma_m < 0.0 or location_bound_m < location_sigma_m:
            raise ValueError("need 0 <= location_sigma_m <= location_bound_m")
        self.track_map = track_map
        self.rng = rng
        self.location_sigma_m = location_sigma_m
        self.location_bound_m = location_bound_m
        self.faults = faults or BaliseReaderFaults()
        self.read = 0
        self.missed = 0
        self.last_errors_m: dict[int, float] = {}
        self._time_s = 0.0
        self._position_m: float | None = None
        self._furthest_m = 0.0
        self._errors_m: dict[tuple[int, int], float] = {}
        """The drawn error of each pass not yet read, by (group id, lap)."""
        self._done: set[tuple[int, int]] = set()
        """The passes read, lost, or behind the start, still near enough to be seen again."""

    def step(self, time_s: float, front_position_m: float) -> list[BaliseDetection]:
        """The groups read since the last step.

        Parameters
        ----------
        time_s : float
            The tick's instant [s].
        front_position_m : float
            The true front-end position [m], unwrapped on a ring (it keeps counting past the
            origin). The first step only places the reader: a group whose reading point lies
            at or behind it is not read.

        Returns
        -------
        list of BaliseDetection
            In the order met, each at the instant [s] interpolated within the tick at which
            the front passed the group's location plus the reading's error.
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
        detections: list[BaliseDetection] = []
        for key, group, location_m in self._passes(front_position_m):
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
            self.last_errors_m[group.id] = error_m
            if self.faults.missed(group.id, detection_s):
                self.missed += 1
                continue
            self.read += 1
            detections.append(BaliseDetection(time_s=detection_s, group=group))
        self._furthest_m = front_position_m
        detections.sort(key=lambda detection: detection.time_s)
        return detections

    def _passes(self, front_m: float) -> list[tuple[tuple[int, int], BaliseGroup, float]]:
        """The passes over a group whose reading point may lie between the furthest position
        and ``front_m`` [m]: (group id, lap), the group, its unwrapped location [m]. Passes
        left behind for good are forgotten."""
        bound_m = self.location_bound_m
        start_m = self._furthest_m - bound_m
        ahead = self.track_map.balise_groups_ahead(start_m, front_m + bound_m - start_m)
        length_m = self.track_map.length_m
        ring = self.track_map.line.ring
        passes: list[tuple[tuple[int, int], BaliseGroup, float]] = []
        for group, distance_m in ahead:
            location_m = start_m + distance_m
            lap = round((location_m - group.position_m) / length_m) if ring else 0
            passes.append(((group.id, lap), group, location_m))
        # A pass before the window's start can never come back into it (the start only moves
        # forward); its error was used.
        keys = {key for key, _, _ in passes}
        self._done &= keys
        return passes

    def _error_m(self, key: tuple[int, int]) -> float:
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
