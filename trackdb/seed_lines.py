"""The lines shipped with ``ato``. Synthetic, but physically plausible.

``bologna-ring`` follows the field test of seed 000: a ring of about 5.7 km, ETCS Level 1, three
stopping points, line speed above the journey's 40 km/h cap. Its gradients, curves and speeds are
invented for the emulation (the seed gives none); they stay within what a test circuit has.
"""

from __future__ import annotations

from collections.abc import Callable

from trackdb.schema import Line, ProfileSection, StoppingPoint

__all__ = ["SEED_LINES", "load_seed_line"]

KMH = 1.0 / 3.6


def _sections(edges: list[float], values: list[float]) -> tuple[ProfileSection, ...]:
    return tuple(
        ProfileSection(start_m=start, end_m=end, value=value)
        for start, end, value in zip(edges[:-1], edges[1:], values, strict=True)
    )


def bologna_ring() -> Line:
    length_m = 5700.0
    return Line(
        id="bologna-ring",
        name="Bologna test ring (synthetic)",
        length_m=length_m,
        ring=True,
        gradient_permille=_sections(
            [0.0, 600.0, 1500.0, 2200.0, 3100.0, 3900.0, 4800.0, length_m],
            [0.0, 4.0, 1.5, -3.0, 0.0, -2.5, 2.0],
        ),
        curve_radius_m=(
            ProfileSection(start_m=900.0, end_m=1400.0, value=450.0),
            ProfileSection(start_m=2700.0, end_m=3300.0, value=380.0),
            ProfileSection(start_m=4900.0, end_m=5500.0, value=500.0),
        ),
        speed_limit_mps=_sections(
            [0.0, 900.0, 1400.0, 2700.0, 3300.0, 4900.0, 5500.0, length_m],
            [v * KMH for v in (80.0, 60.0, 80.0, 55.0, 80.0, 60.0, 80.0)],
        ),
        stopping_points=(
            StoppingPoint(id="north", name="North platform", position_m=450.0),
            StoppingPoint(id="east", name="East platform", position_m=2250.0),
            StoppingPoint(id="south", name="South platform", position_m=4150.0),
        ),
    )


SEED_LINES: dict[str, Callable[[], Line]] = {"bologna-ring": bologna_ring}


def load_seed_line(line_id: str) -> Line:
    """The shipped line of that id; ``KeyError`` names the known ones."""
    try:
        return SEED_LINES[line_id]()
    except KeyError:
        raise KeyError(f"no seed line {line_id!r}; known: {', '.join(SEED_LINES)}") from None
