"""The balise transmission module (BTM): balise groups read under the antenna, as the train does.

The BTM reads a group's telegram as the antenna passes over it and reports the instant it
located the group's centre, with a location error (SUBSET-036 allows ±1 m): the front end was
then near the group, not exactly on it. The reading itself, once per pass and forwards only, is
:class:`~onboard.plant.point_reader.PointReader`'s. A fault option makes chosen groups, or
every group in chosen time windows, go unread (the scenario ``balise-missed``). Error sources
and values: docs/sensors.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from onboard.plant.point_reader import PointReader
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


class BaliseReader(PointReader[BaliseGroup, BaliseDetection]):
    """The BTM: the true front-end position in, :class:`BaliseDetection` out, one plant tick at
    a time (:class:`~onboard.plant.point_reader.PointReader`).

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
        super().__init__(
            track_map,
            rng=rng,
            location_sigma_m=location_sigma_m,
            location_bound_m=location_bound_m,
        )
        self.faults = faults or BaliseReaderFaults()

    def points_ahead(self, chainage_m: float, distance_m: float) -> list[tuple[BaliseGroup, float]]:
        return self.track_map.balise_groups_ahead(chainage_m, distance_m)

    def identity(self, point: BaliseGroup) -> int:
        return point.id

    def chainage_m(self, point: BaliseGroup) -> float:
        return point.position_m

    def detection(self, time_s: float, point: BaliseGroup) -> BaliseDetection:
        return BaliseDetection(time_s=time_s, group=point)

    def lost(self, point: BaliseGroup, time_s: float) -> bool:
        return self.faults.missed(point.id, time_s)

    @staticmethod
    def time_of(detection: BaliseDetection) -> float:
        return detection.time_s
