"""Step functions along a line and the walks over them, behind :class:`~trackdb.TrackMap`.

The line's own profiles (gradient, curve radius, line speed) are piecewise constant with gaps
between sections (:class:`Profile`). The MRSP is a step function that covers the whole line
(:class:`Steps`): :func:`build_mrsp` builds it from the SSP and the TSRs in force, once at
start and again only when a TSR changes. :func:`window_sections` and :func:`points_ahead` walk
ahead of a chainage, lap after lap across a ring's origin.

TrackMap answers its point queries itself, with one bisection over these lists and no further
call; what lives here is built once or runs once per window.
"""

from __future__ import annotations

import bisect
from collections.abc import Mapping, Sequence
from typing import NamedTuple, TypeVar

import numpy as np

from trackdb.schema import Line, ProfileSection, TemporarySpeedRestriction

# Only SpeedSection is public (trackdb re-exports it); the rest serves TrackMap alone.
__all__ = ["SpeedSection"]

Point = TypeVar("Point")


class SpeedSection(NamedTuple):
    """A constant speed [m/s] from ``from_distance_m`` to ``to_distance_m`` [m] ahead."""

    from_distance_m: float
    to_distance_m: float
    speed_mps: float


class Profile:
    """Piecewise-constant lookup by bisection over section starts."""

    def __init__(self, sections: tuple[ProfileSection, ...], default: float) -> None:
        self._starts = [section.start_m for section in sections]
        self._ends = [section.end_m for section in sections]
        self._values = [section.value for section in sections]
        self._default = default

    def at(self, chainage_m: float) -> float:
        index = bisect.bisect_right(self._starts, chainage_m) - 1
        if index >= 0 and chainage_m < self._ends[index]:
            return self._values[index]
        return self._default


class Steps:
    """A step function covering ``[0, length_m)``: ``values[i]`` from ``starts[i]`` on."""

    __slots__ = ("ends", "starts", "starts_array", "values", "values_array")

    def __init__(self, starts: list[float], values: list[float], length_m: float) -> None:
        self.starts = starts
        self.values = values
        self.ends = [*starts[1:], length_m]
        self.starts_array = np.asarray(starts, dtype=np.float64)
        self.values_array = np.asarray(values, dtype=np.float64)


def build_mrsp(
    line: Line, ssp: Profile, restrictions: Mapping[str, TemporarySpeedRestriction]
) -> Steps:
    """The SSP lowered by every TSR, merged into steps over ``[0, length_m)``.

    Parameters
    ----------
    line : Line
        The line: its SSP sections give the cuts, its length [m] the extent.
    ssp : Profile
        The line's SSP [m/s] as a lookup.
    restrictions : mapping of str to TemporarySpeedRestriction
        The TSRs in force, by identity.

    Returns
    -------
    Steps
        The MRSP [m/s], one step per change of speed.
    """
    length_m = line.length_m
    cuts = {section.start_m for section in line.speed_limit_mps}
    for restriction in restrictions.values():
        cuts.update((restriction.start_m, restriction.end_m))
    starts: list[float] = []
    values: list[float] = []
    for start_m in sorted(cut for cut in cuts if cut < length_m):
        speed_mps = ssp.at(start_m)
        for restriction in restrictions.values():
            if restriction.start_m <= start_m < restriction.end_m:
                speed_mps = min(speed_mps, restriction.speed_mps)
        if not values or values[-1] != speed_mps:
            starts.append(start_m)
            values.append(speed_mps)
    return Steps(starts, values, length_m)


def window_sections(
    steps: Steps, origin_m: float, limit_m: float, lap_length_m: float
) -> list[SpeedSection]:
    """The steps from ``origin_m`` over ``limit_m`` ahead, as merged sections of distance.

    Parameters
    ----------
    steps : Steps
        The step function [m/s] over one lap.
    origin_m : float
        Chainage [m] the window starts at, on the line.
    limit_m : float
        Length [m] of the window; past the lap's end the walk goes on from chainage 0.
    lap_length_m : float
        The line's length [m], one lap.

    Returns
    -------
    list of SpeedSection
        Contiguous sections from distance 0 to ``limit_m`` [m], merged where the speed [m/s]
        is the same; empty when ``limit_m`` is 0.
    """
    index = max(bisect.bisect_right(steps.starts, origin_m) - 1, 0)
    sections: list[SpeedSection] = []
    lap_m = from_m = 0.0
    while from_m < limit_m:
        # Measured from the window's origin in unwrapped chainage, so that the ends grow
        # with every step and the loop ends whatever the rounding.
        to_m = min(lap_m + steps.ends[index] - origin_m, limit_m)
        speed_mps = steps.values[index]
        if sections and sections[-1].speed_mps == speed_mps:
            sections[-1] = SpeedSection(sections[-1].from_distance_m, to_m, speed_mps)
        elif to_m > from_m:
            sections.append(SpeedSection(from_m, to_m, speed_mps))
        from_m = max(from_m, to_m)
        index += 1
        if index == len(steps.values):
            index, lap_m = 0, lap_m + lap_length_m
    return sections


def points_ahead(
    points: Sequence[Point],
    positions_m: Sequence[float],
    position_m: float,
    distance_m: float,
    *,
    ring_length_m: float | None,
) -> list[tuple[Point, float]]:
    """The points from ``position_m`` to ``distance_m`` [m] ahead, both included.

    Parameters
    ----------
    points : sequence
        The points, sorted by position.
    positions_m : sequence of float
        Their chainages [m], ascending.
    position_m : float
        Chainage [m] on the line the walk starts from.
    distance_m : float
        How far [m] ahead the walk goes.
    ring_length_m : float or None
        The ring's length [m], after which the walk goes on from chainage 0; None on an open
        line, where it ends at the last point.

    Returns
    -------
    list of (point, float)
        Each point with its distance [m] ahead, in the order the train meets them; once per
        lap on a ring.
    """
    index = bisect.bisect_left(positions_m, position_m)
    ahead: list[tuple[Point, float]] = []
    lap_m = 0.0
    while positions_m:
        if index == len(positions_m):
            if ring_length_m is None:
                break
            index, lap_m = 0, lap_m + ring_length_m
        point_distance_m = lap_m + positions_m[index] - position_m
        if point_distance_m > distance_m:
            break
        ahead.append((points[index], point_distance_m))
        index += 1
    return ahead
