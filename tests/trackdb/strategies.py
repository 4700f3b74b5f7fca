"""Hypothesis strategies for lines, built with LineBuilder from drawn walks.

Lengths and positions are whole metres so that the builder's walk along the profiles adds up
exactly; speeds, gradients, radii, headings and the origin are arbitrary floats.
"""

from __future__ import annotations

from hypothesis import strategies as st

from trackdb import Line, LineBuilder
from trackdb.schema import LevelTransitionPacket

__all__ = ["lines"]

identifiers = st.from_regex(r"[a-z0-9][a-z0-9_-]{0,20}", fullmatch=True)
names = st.text(
    alphabet=st.characters(codec="utf-8", exclude_categories=("Cs", "Cc")), min_size=1, max_size=40
)


def _finite(low: float, high: float) -> st.SearchStrategy[float]:
    return st.floats(low, high, allow_nan=False, allow_infinity=False)


@st.composite
def lines(draw: st.DrawFn) -> Line:
    """A valid line: 1–5 stretches, stopping points, balise groups and TSRs on it."""
    builder = LineBuilder(
        id=draw(identifiers),
        name=draw(names),
        ring=draw(st.booleans()),
        etcs_level=draw(st.sampled_from([1, 2])),
        origin_lat_deg=draw(_finite(-60.0, 60.0)),
        origin_lon_deg=draw(_finite(-170.0, 170.0)),
        origin_alt_m=draw(_finite(0.0, 2000.0)),
        heading_deg=draw(_finite(-180.0, 180.0)),
    )
    for _ in range(draw(st.integers(1, 5))):
        length_m = float(draw(st.integers(20, 3000)))
        speed_kmh = draw(_finite(10.0, 350.0))
        gradient = draw(_finite(-20.0, 20.0))
        if draw(st.booleans()):
            radius_m = draw(_finite(50.0, 20_000.0)) * draw(st.sampled_from([-1.0, 1.0]))
            builder.curve(length_m, radius_m, speed_kmh=speed_kmh, gradient_permille=gradient)
        else:
            builder.straight(length_m, speed_kmh=speed_kmh, gradient_permille=gradient)
    length_m = int(builder.length_m)
    positions = st.integers(0, length_m - 1).map(float)
    for index, position in enumerate(draw(st.lists(positions, max_size=3, unique=True))):
        builder.stopping_point(f"stop-{index}", f"Stop {index}", position)
    group_positions = draw(st.lists(positions, max_size=4, unique=True))
    for index, position in enumerate(sorted(group_positions)):
        packets = (LevelTransitionPacket(distance_m=draw(_finite(0.0, 500.0)), level=2),)
        authority = draw(st.none() | st.integers(1, length_m).map(float))
        builder.balise_group(100 + index, position, authority_m=authority, packets=packets)
    for index in range(draw(st.integers(0, 2))):
        start = draw(st.integers(0, length_m - 1))
        end = draw(st.integers(start + 1, length_m))
        speed = draw(_finite(5.0, 100.0))
        builder.temporary_speed_restriction(f"tsr-{index}", start, end, speed_kmh=speed)
    return builder.build(geodetic_step_m=max(10.0, length_m / 40.0))
