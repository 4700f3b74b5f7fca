"""Small named track layouts for tests, built with LineBuilder (after OSRD's tiny/small infra).

- ``tiny_line``: an open line of 1000 m: a straight, a left curve, a straight; one stopping
  point, two balise groups, one TSR.
- ``small_ring``: a ring of 2000 m: four quarter circles of 150 m radius joined by straights;
  line speed lower in the curves; two stopping points, two balise groups.
- ``without_geodetic``: a line with its geodetic polyline removed.
"""

from __future__ import annotations

import math

from trackdb import Line, LineBuilder, parse_line

__all__ = [
    "SMALL_RING_LENGTH_M",
    "TINY_LINE_LENGTH_M",
    "small_ring",
    "tiny_line",
    "without_geodetic",
]

TINY_LINE_LENGTH_M = 1000.0
SMALL_RING_LENGTH_M = 2000.0
SMALL_RING_RADIUS_M = 150.0


def tiny_line(*, name: str = "Tiny line", tsr_speed_kmh: float = 30.0) -> Line:
    """1000 m open line: 72 km/h straights, a 54 km/h left curve of 300 m radius at 400–600 m.

    The TSR holds 350–450 m; ``name`` and ``tsr_speed_kmh`` make other versions of the line.
    """
    builder = LineBuilder(id="tiny", name=name)
    builder.straight(400.0, speed_kmh=72.0, gradient_permille=5.0)
    builder.curve(200.0, 300.0, speed_kmh=54.0)
    builder.straight(400.0, speed_kmh=72.0, gradient_permille=-3.0)
    builder.stopping_point("end", "End platform", 950.0)
    builder.balise_group(1, 50.0, authority_m=800.0)
    builder.balise_group(2, 700.0)
    builder.temporary_speed_restriction("works", 350.0, 450.0, speed_kmh=tsr_speed_kmh)
    return builder.build(geodetic_step_m=20.0)


def small_ring() -> Line:
    """2000 m ring: straights at 60 km/h, quarter curves of 150 m radius at 40 km/h."""
    quarter = SMALL_RING_RADIUS_M * math.pi / 2.0
    straight = (SMALL_RING_LENGTH_M - 4 * quarter) / 4.0
    builder = LineBuilder(id="small-ring", name="Small ring", ring=True)
    for _ in range(4):
        builder.straight(straight, speed_kmh=60.0, gradient_permille=1.0)
        builder.curve(quarter, SMALL_RING_RADIUS_M, speed_kmh=40.0, gradient_permille=-1.0)
    builder.stopping_point("a", "Platform A", 100.0)
    builder.stopping_point("b", "Platform B", 1100.0)
    builder.balise_group(11, 20.0, authority_m=1000.0)
    builder.balise_group(12, 1020.0, authority_m=1000.0)
    return builder.build(geodetic_step_m=10.0)


def without_geodetic(line: Line) -> Line:
    """The same line with no geodetic polyline (so no altitude)."""
    return parse_line(line.model_dump(mode="json") | {"geodetic": []})
