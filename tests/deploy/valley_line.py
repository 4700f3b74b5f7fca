"""A small line of our own for the tests of scenarios and of the planner on a user's line."""

from __future__ import annotations

from trackdb import Line, LineBuilder

__all__ = ["valley_line"]


def valley_line(line_id: str = "valley-test") -> Line:
    """A 3.2 km Level 2 line of our own: curves both ways, three line speeds, gradients, three
    stopping points each with a precision-stop marker, balise groups as location references."""
    builder = LineBuilder(
        id=line_id, name="Valley test line", etcs_level=2, origin_lat_deg=46.0, origin_lon_deg=8.9
    )
    builder.straight(600, speed_kmh=60, gradient_permille=3.0)
    builder.curve(500, 600.0, speed_kmh=60, gradient_permille=5.0)
    builder.straight(700, speed_kmh=40, gradient_permille=-4.0)
    builder.curve(400, -500.0, speed_kmh=40)
    builder.straight(1000, speed_kmh=50, gradient_permille=2.0)
    for stop_id, name, position in (("a", "Alpha", 800.0), ("b", "Bravo", 1800.0)):
        builder.stopping_point(stop_id, name, position)
        builder.stop_marker(f"{stop_id}-marker", position - 30.0)
    builder.stopping_point("c", "Charlie", 3000.0)
    builder.stop_marker("c-marker", 2970.0)
    for index, position in enumerate(range(50, 3200, 500)):
        builder.balise_group(200 + index, float(position))
    return builder.build(geodetic_step_m=10.0)
