"""TrackMap: the fast, read-only view of a line that the onboard side queries every cycle."""

from __future__ import annotations

import bisect
import math

from trackdb.schema import Line, ProfileSection

__all__ = ["TrackMap"]


class _Profile:
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


class TrackMap:
    """Gradient, curvature and line speed at a chainage, with ring wrap-around."""

    def __init__(self, line: Line) -> None:
        self.line = line
        self.version = line.version()
        self._gradient = _Profile(line.gradient_permille, 0.0)
        self._radius = _Profile(line.curve_radius_m, math.inf)
        self._speed = _Profile(line.speed_limit_mps, 0.0)

    @property
    def length_m(self) -> float:
        return self.line.length_m

    def normalise(self, chainage_m: float) -> float:
        """The chainage on the line: wrapped on a ring, clamped to the ends otherwise."""
        if self.line.ring:
            return chainage_m % self.line.length_m
        return min(max(chainage_m, 0.0), math.nextafter(self.line.length_m, 0.0))

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
        """Static line speed [m/s] at the chainage."""
        return self._speed.at(self.normalise(chainage_m))
