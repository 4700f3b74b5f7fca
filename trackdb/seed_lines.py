"""The lines shipped with ``ato``: synthetic, but physically plausible.

- ``bologna-ring``: the test ring of the seed 000 field test. About 5.7 km, ETCS Level 1: a
  rounded rectangle (two 1100 m and two 493 m straights, four quarter circles of 400 m radius,
  turning left), gentle gradients that close in altitude, line speed 80 km/h on the straights and
  60 km/h in the curves (so the journey's 40 km/h cap is the operator's choice), three stopping
  points (±0.5 m) each with a precision-stop marker 30 m before it, and four balise groups whose
  movement authorities let a train run round the ring; the first, 150 m from the origin, is the
  one that brings Full Supervision.
- ``milano-bologna``: a high-speed line of 200 km for the seed 003 mission, ETCS Level 2:
  300 km/h with 120–250 km/h sections near the ends and at a junction, large-radius curves,
  gradients within ±12 ‰, stations at both ends and four intermediate stopping points, a balise
  group every 5 km as location reference.

The seeds give no line data: the geometry, speeds and gradients are invented to fit what they
describe; the geodetic polylines start near Bologna and Milano.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

from trackdb.builder import LineBuilder
from trackdb.schema import Line

__all__ = ["SEED_LINES", "bologna_ring", "load_seed_line", "milano_bologna"]

RING_RADIUS_M = 400.0
RING_LONG_STRAIGHT_M = 1100.0
RING_LENGTH_M = 5700.0
STOP_MARKER_BEFORE_M = 30.0
"""The ring's precision-stop markers lie this far before its stopping points [m]: passed in the
final braking, some 5 s before the stop at the plans' 0.5 m/s², early enough for the controller
to take up the fix's correction, late enough that little odometry error builds up after it."""


def bologna_ring() -> Line:
    """The seed 000 field-test ring, in Level 1: each balise group gives the MA to the group
    after the next."""
    return _ring("bologna-ring", "Bologna test ring (synthetic)", etcs_level=1)


def bologna_ring_level_2() -> Line:
    """The same ring in Level 2: MAs come from the RBC alone, its balise groups only locate
    the train. The shared line of the multi-train scenarios: fixed Level 1 MAs would let a
    train behind run into one ahead, where the RBC keeps them apart."""
    return _ring("bologna-ring-l2", "Bologna test ring in ETCS Level 2 (synthetic)", etcs_level=2)


def _ring(line_id: str, name: str, *, etcs_level: int) -> Line:
    quarter = RING_RADIUS_M * math.pi / 2.0
    short = (RING_LENGTH_M - 2 * RING_LONG_STRAIGHT_M - 4 * quarter) / 2.0
    # Altitude gained on the straights is lost in the last curve, so the ring closes.
    closing_gradient = -(short * 1.0) / quarter
    builder = LineBuilder(
        id=line_id,
        name=name,
        ring=True,
        etcs_level=etcs_level,
        origin_lat_deg=44.5120,
        origin_lon_deg=11.3180,
        origin_alt_m=42.0,
        heading_deg=0.0,
    )
    (
        builder.straight(RING_LONG_STRAIGHT_M, speed_kmh=80, gradient_permille=2.0)
        .curve(quarter, RING_RADIUS_M, speed_kmh=60, gradient_permille=1.0)
        .straight(short, speed_kmh=80, gradient_permille=0.0)
        .curve(quarter, RING_RADIUS_M, speed_kmh=60, gradient_permille=-1.0)
        .straight(RING_LONG_STRAIGHT_M, speed_kmh=80, gradient_permille=-2.0)
        .curve(quarter, RING_RADIUS_M, speed_kmh=60, gradient_permille=0.0)
        .straight(short, speed_kmh=80, gradient_permille=1.0)
        .curve(quarter, RING_RADIUS_M, speed_kmh=60, gradient_permille=closing_gradient)
    )
    stops = {
        "north": ("North platform", 550.0),
        "east": ("East platform", 1100.0 + quarter + short / 2.0),
        "south": ("South platform", 1100.0 + 2 * quarter + short + 550.0),
    }
    for stop_id, (name, position) in stops.items():
        builder.stopping_point(stop_id, name, position)
        builder.stop_marker(f"{stop_id}-marker", position - STOP_MARKER_BEFORE_M)
    groups = (101, 150.0), (102, 1800.0), (103, 2950.0), (104, 4650.0)
    for index, (group_id, position) in enumerate(groups):
        after_next = groups[(index + 2) % len(groups)][1]
        authority = (after_next - position) % RING_LENGTH_M
        builder.balise_group(group_id, position, authority_m=authority if etcs_level == 1 else None)
    return builder.build(geodetic_step_m=10.0)


MILANO_BOLOGNA_LENGTH_M = 200_000.0


def milano_bologna() -> Line:
    builder = LineBuilder(
        id="milano-bologna",
        name="Milano – Bologna high-speed line (synthetic)",
        ring=False,
        etcs_level=2,
        origin_lat_deg=45.4340,
        origin_lon_deg=9.2380,
        origin_alt_m=105.0,
        heading_deg=-43.5,
    )
    # (length [m], radius [m] or None, speed [km/h], gradient [‰])
    walk: list[tuple[float, float | None, float, float]] = [
        (4_000, None, 120, 0.0),
        (6_000, None, 200, -2.0),
        (12_000, None, 300, -1.0),
        (3_000, 6_000, 300, 0.0),
        (20_000, None, 300, 1.5),
        (5_000, None, 300, 12.0),
        (5_000, None, 300, -12.0),
        (3_000, -6_500, 300, 0.0),
        (22_000, None, 300, -1.0),
        (8_000, None, 250, 0.0),
        (2_500, 7_000, 250, 0.0),
        (9_500, None, 300, -2.0),
        (25_000, None, 300, 0.5),
        (3_000, -6_000, 300, 0.0),
        (20_000, None, 300, -1.0),
        (4_000, None, 300, 10.0),
        (4_000, None, 300, -10.0),
        (2_500, 6_500, 300, 0.0),
        (31_500, None, 300, -0.5),
        (6_000, None, 200, -1.0),
        (4_000, None, 120, 0.0),
    ]
    for length, radius, speed, gradient in walk:
        if radius is None:
            builder.straight(length, speed_kmh=speed, gradient_permille=gradient)
        else:
            builder.curve(length, radius, speed_kmh=speed, gradient_permille=gradient)
    stations = [
        ("milano-rogoredo", "Milano Rogoredo", 500.0),
        ("lodi", "Lodi junction", 30_000.0),
        ("parma", "Parma junction", 92_000.0),
        ("reggio-emilia", "Reggio Emilia AV Mediopadana", 128_000.0),
        ("modena", "Modena junction", 158_000.0),
        ("bologna-centrale", "Bologna Centrale AV", 199_000.0),
    ]
    for stop_id, name, position in stations:
        builder.stopping_point(stop_id, name, position, tolerance_m=2.0, platform_length_m=400.0)
    for index, position in enumerate(range(1_000, 200_000, 5_000)):
        builder.balise_group(1_000 + index, float(position))
    return builder.build(geodetic_step_m=50.0)


SEED_LINES: dict[str, Callable[[], Line]] = {
    "bologna-ring": bologna_ring,
    "milano-bologna": milano_bologna,
    "bologna-ring-l2": bologna_ring_level_2,
}


@functools.cache
def load_seed_line(line_id: str) -> Line:
    """The shipped line of that id (built once, lines are immutable); ``KeyError`` names the
    known ones."""
    try:
        return SEED_LINES[line_id]()
    except KeyError:
        raise KeyError(f"no seed line {line_id!r}; known: {', '.join(SEED_LINES)}") from None
