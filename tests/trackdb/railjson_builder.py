"""A small builder of RailJSON infrastructures (OSRD's format, 3.5.0), and the layouts we test on.

Tracks are described as a walk (straights and curves with gradients, a curve's radius positive
turning left in the walking direction, as in :class:`trackdb.LineBuilder`); the builder writes
each as a RailJSON track section, geometry (sampled every 25 m), slopes and curves, stored
forwards (BEGIN where the walk starts) or, with ``reverse=True``, backwards, so that tests cover
both directions. Curves are written with RailJSON's radius sign as our import reads it (positive
curving right seen from BEGIN: docs/trackdb.md).

Layouts:

- :func:`junction_valley`: the test infrastructure of issue 21, committed as
  ``deploy/lines/junction-valley.railjson.json``. Regenerate that file with::

      .venv/bin/python -m tests.trackdb.railjson_builder \
          > deploy/lines/junction-valley.railjson.json

- :func:`long_line`: a chain of sections joined by links, for long paths;
- :func:`twin_tracks`: two equally long tracks between two switches, for the tie rule.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from trackdb.builder import enu_to_geodetic

__all__ = [
    "JUNCTION_VALLEY_ORIGIN",
    "Pose",
    "RailJsonBuilder",
    "Stretch",
    "TrackHandle",
    "junction_valley",
    "long_line",
    "twin_tracks",
]

JUNCTION_VALLEY_ORIGIN = (46.2300, 7.3600)
GEO_STEP_M = 25.0
Along = Literal["walk", "against", "both"]


@dataclass(frozen=True)
class Pose:
    """East, north [m] from the builder's origin, heading counterclockwise from east [rad]."""

    east: float = 0.0
    north: float = 0.0
    heading: float = 0.0


@dataclass(frozen=True)
class Stretch:
    length_m: float
    radius_m: float | None = None
    """Positive turning left in the walking direction; None: straight."""
    gradient_permille: float = 0.0
    """Positive uphill in the walking direction."""


def straight(length_m: float, gradient: float = 0.0) -> Stretch:
    return Stretch(length_m, None, gradient)


def curve(length_m: float, radius_m: float, gradient: float = 0.0) -> Stretch:
    return Stretch(length_m, radius_m, gradient)


@dataclass(frozen=True)
class TrackHandle:
    id: str
    length_m: float
    reverse: bool
    end_pose: Pose

    @property
    def entry(self) -> tuple[str, str]:
        """The (track, endpoint) where the walk starts."""
        return self.id, "END" if self.reverse else "BEGIN"

    @property
    def exit(self) -> tuple[str, str]:
        return self.id, "BEGIN" if self.reverse else "END"

    def offset(self, walked_m: float) -> float:
        """The track offset of a distance walked [m]."""
        return self.length_m - walked_m if self.reverse else walked_m


@dataclass
class RailJsonBuilder:
    origin_lat_deg: float
    origin_lon_deg: float
    version: str = "3.5.0"
    document: dict[str, list[Any]] = field(
        default_factory=lambda: {
            name: []
            for name in (
                "operational_points",
                "routes",
                "switches",
                "extended_switch_types",
                "track_sections",
                "speed_sections",
                "electrifications",
                "signals",
                "buffer_stops",
                "detectors",
                "neutral_sections",
                "level_crossings",
            )
        }
    )
    handles: dict[str, TrackHandle] = field(default_factory=dict)

    def track(
        self, id: str, start: Pose, stretches: Sequence[Stretch], *, reverse: bool = False
    ) -> TrackHandle:
        length = sum(s.length_m for s in stretches)
        points, pose = self._walk(start, stretches)
        slopes, curves = [], []
        walked = 0.0
        for s in stretches:
            begin, end = walked, walked + s.length_m
            if reverse:
                begin, end = length - end, length - begin
            sign = -1.0 if reverse else 1.0
            if s.gradient_permille:
                slopes.append({"gradient": sign * s.gradient_permille, "begin": begin, "end": end})
            if s.radius_m is not None:
                # RailJSON: positive curving right seen from BEGIN.
                curves.append({"radius": -sign * s.radius_m, "begin": begin, "end": end})
            walked += s.length_m
        if reverse:
            points.reverse()
        self.document["track_sections"].append(
            {
                "id": id,
                "length": length,
                "slopes": sorted(slopes, key=lambda r: r["begin"]),
                "curves": sorted(curves, key=lambda r: r["begin"]),
                "loading_gauge_limits": [],
                "geo": {"type": "LineString", "coordinates": points},
            }
        )
        handle = TrackHandle(id, length, reverse, pose)
        self.handles[id] = handle
        return handle

    def _walk(self, pose: Pose, stretches: Sequence[Stretch]) -> tuple[list[list[float]], Pose]:
        east, north, heading = pose.east, pose.north, pose.heading
        points = [self._lon_lat(east, north)]
        for s in stretches:
            steps = max(1, math.ceil(s.length_m / GEO_STEP_M))
            ds = s.length_m / steps
            for _ in range(steps):
                if s.radius_m is None:
                    east += ds * math.cos(heading)
                    north += ds * math.sin(heading)
                else:
                    turned = heading + ds / s.radius_m
                    east += (math.sin(turned) - math.sin(heading)) * s.radius_m
                    north -= (math.cos(turned) - math.cos(heading)) * s.radius_m
                    heading = turned
                points.append(self._lon_lat(east, north))
        return points, Pose(east, north, heading)

    def _lon_lat(self, east: float, north: float) -> list[float]:
        lat, lon = enu_to_geodetic(east, north, self.origin_lat_deg, self.origin_lon_deg)
        return [round(lon, 8), round(lat, 8)]

    def node(self, id: str, switch_type: str, ports: dict[str, tuple[str, str]]) -> None:
        self.document["switches"].append(
            {
                "id": id,
                "switch_type": switch_type,
                "group_change_delay": 4.0,
                "ports": {
                    port: {"endpoint": endpoint, "track": track}
                    for port, (track, endpoint) in ports.items()
                },
            }
        )

    def link(self, id: str, a: tuple[str, str], b: tuple[str, str]) -> None:
        self.node(id, "link", {"A": a, "B": b})

    def point_switch(
        self, id: str, a: tuple[str, str], b1: tuple[str, str], b2: tuple[str, str]
    ) -> None:
        self.node(id, "point_switch", {"A": a, "B1": b1, "B2": b2})

    def four_port(self, id: str, kind: str, *ends: tuple[str, str]) -> None:
        """A crossing or a slip switch: ports A1, B1, A2, B2 in that order."""
        self.node(id, kind, dict(zip(("A1", "B1", "A2", "B2"), ends, strict=True)))

    def speed_section(
        self,
        id: str,
        speed_kmh: float | None,
        ranges: Sequence[tuple[str, float, float, Along]],
        *,
        by_tag_kmh: dict[str, float] | None = None,
    ) -> None:
        """Ranges in distances walked along each track; ``along`` the walk, against it, both."""
        track_ranges = []
        for track_id, walked_from, walked_to, along in ranges:
            handle = self.handles[track_id]
            begin, end = sorted((handle.offset(walked_from), handle.offset(walked_to)))
            forwards = (
                along == "walk" and not handle.reverse or along == "against" and handle.reverse
            )
            directions = (
                "BOTH" if along == "both" else "START_TO_STOP" if forwards else "STOP_TO_START"
            )
            track_ranges.append(
                {"track": track_id, "begin": begin, "end": end, "applicable_directions": directions}
            )
        self.document["speed_sections"].append(
            {
                "id": id,
                "speed_limit": None if speed_kmh is None else speed_kmh / 3.6,
                "speed_limit_by_tag": {k: v / 3.6 for k, v in (by_tag_kmh or {}).items()},
                "track_ranges": track_ranges,
                "on_routes": None,
            }
        )

    def operational_point(self, id: str, name: str, parts: Sequence[tuple[str, float]]) -> None:
        self.document["operational_points"].append(
            {
                "id": id,
                "parts": [
                    {"track": track, "position": self.handles[track].offset(walked)}
                    for track, walked in parts
                ],
                "extensions": {"identifier": {"name": name, "uic": 0}},
            }
        )

    def point_object(self, kind: str, id: str, track: str, walked_m: float) -> None:
        """A detector or a buffer stop (``kind``: ``detectors``, ``buffer_stops``)."""
        self.document[kind].append(
            {"id": id, "track": track, "position": self.handles[track].offset(walked_m)}
        )

    def build(self) -> dict[str, Any]:
        return {"version": self.version, **self.document}

    def dumps(self) -> str:
        return json.dumps(self.build(), indent=1) + "\n"


def _s_curve(radius_m: float, arc_m: float) -> list[Stretch]:
    """Out to a parallel track on the left (radius > 0) or right, and straight again."""
    return [curve(arc_m, radius_m), curve(arc_m, -radius_m)]


def junction_valley() -> RailJsonBuilder:
    """Westbrook – Millbridge – Valley Junction – Eastfield: 9 km of main line (ids ``main-01``
    to ``main-12``) through point switches, a link, a crossing with a north–south freight line,
    and a double slip at Eastfield; a passing loop at Millbridge, a branch to Northgate, a depot,
    a yard; 100, 80 and 60 km/h, a westbound-only 40 km/h section and a freight-only limit;
    gradients within ±12 ‰, radii of 300 m and more. 30 track sections, 17 nodes."""
    b = RailJsonBuilder(*JUNCTION_VALLEY_ORIGIN)
    m01 = b.track("main-01", Pose(), [straight(900)])
    depot = b.track("depot", m01.end_pose, [curve(80, -300), straight(320)])
    m02 = b.track("main-02", m01.end_pose, [straight(300, 5), curve(600, 1500, 5)])
    m03 = b.track("main-03", m02.end_pose, [straight(900)])
    m04 = b.track("main-04", m03.end_pose, [straight(700)])
    loop = b.track(
        "millbridge-2", m03.end_pose, [*_s_curve(500, 50), straight(500.3), *_s_curve(-500, 50)]
    )
    m05 = b.track(
        "main-05",
        m04.end_pose,
        [straight(800, -8), curve(500, -800, -8), straight(300, -8)],
        reverse=True,
    )
    m06 = b.track("main-06", m05.end_pose, [straight(900)], reverse=True)
    crossing_point = m06.end_pose
    m07 = b.track("main-07", crossing_point, [straight(600)])
    m08 = b.track(
        "main-08",
        m07.end_pose,
        [
            straight(400, 10),
            curve(500, -600, 10),
            straight(600, -6),
            curve(500, 600, -6),
            straight(200),
        ],
    )
    m09 = b.track("main-09", m08.end_pose, [straight(400)])
    east1 = b.track("east-01", m08.end_pose, [*_s_curve(500, 50), straight(300.3)])
    m10 = b.track("main-10", m09.end_pose, [straight(800)], reverse=True)
    east2 = b.track("east-02", east1.end_pose, [straight(700.3), *_s_curve(-500, 50)])
    m11 = b.track("main-11", m10.end_pose, [straight(600)])
    m12 = b.track("main-12", m11.end_pose, [straight(400)])
    east3 = b.track("east-03", m11.end_pose, [curve(60, 300), straight(240)])
    _junction_branch(b, m05)
    _freight_line(b, crossing_point)

    b.point_switch("sw-01", m01.exit, m02.entry, depot.entry)
    b.link("lk-04", m02.exit, m03.entry)
    b.point_switch("sw-02", m03.exit, m04.entry, loop.entry)
    b.point_switch("sw-03", m05.entry, m04.exit, loop.exit)
    b.point_switch("sw-04", m05.exit, m06.entry, ("branch-01", "BEGIN"))
    b.four_port("x-01", "crossing", m06.exit, m07.entry, ("cross-01", "END"), ("cross-02", "BEGIN"))
    b.link("lk-01", m07.exit, m08.entry)
    b.point_switch("sw-05", m08.exit, m09.entry, east1.entry)
    b.four_port("ds-01", "double_slip_switch", m09.exit, m10.entry, east1.exit, east2.entry)
    b.point_switch("sw-08", m11.entry, m10.exit, east2.exit)
    b.point_switch("sw-09", m11.exit, m12.entry, east3.entry)

    def whole(*tracks: str) -> list[tuple[str, float, float, Along]]:
        return [(t, 0.0, b.handles[t].length_m, "both") for t in tracks]

    b.speed_section("main-100", 100, whole("main-01", "main-02", "main-03", "main-05", "main-08"))
    stations = ("main-04", "millbridge-2", "main-09", "main-10", "main-11", "east-01", "east-02")
    b.speed_section("stations-80", 80, whole(*stations))
    b.speed_section("junction-60", 60, [("main-06", 0, 900, "both"), ("main-07", 0, 600, "both")])
    b.speed_section("westbound-40", 40, [("main-08", 0, 600, "against")])
    b.speed_section("freight-50", None, [("main-08", 0, 2200, "both")], by_tag_kmh={"freight": 50})

    b.operational_point("westbrook", "Westbrook", [("main-01", 400)])
    b.operational_point("millbridge", "Millbridge", [("main-04", 350), ("millbridge-2", 350)])
    b.operational_point("valley-junction", "Valley Junction", [("main-07", 250)])
    b.operational_point("eastfield", "Eastfield", [("main-10", 300), ("east-02", 300)])
    b.operational_point("northgate", "Northgate", [("branch-02", 300)])
    for number, (track, walked) in enumerate(
        [
            ("main-02", 10),
            ("main-03", 10),
            ("main-04", 10),
            ("main-05", 10),
            ("main-05", 900),
            ("main-06", 10),
            ("main-07", 10),
            ("main-08", 10),
            ("main-08", 1200),
            ("main-09", 10),
            ("main-10", 10),
            ("main-11", 10),
            ("branch-01", 10),
            ("cross-02", 10),
        ],
        start=1,
    ):
        b.point_object("detectors", f"det-{number:02d}", track, walked)
    for track in (
        "depot",
        "main-12",
        "east-03",
        "branch-03",
        "branch-04",
        "yard-03",
        "yard-04",
        "yard-05",
        "yard-06",
    ):
        b.point_object("buffer_stops", f"bs-{track}", track, b.handles[track].length_m)
    b.point_object("buffer_stops", "bs-main-01", "main-01", 0.0)
    return b


def _junction_branch(b: RailJsonBuilder, main_05: TrackHandle) -> None:
    """Valley Junction's branch north to Northgate (platform, siding, stub)."""
    b1 = b.track("branch-01", main_05.end_pose, [curve(300, 500, 12), straight(1200, 12)])
    b2 = b.track("branch-02", b1.end_pose, [straight(800)])
    b3 = b.track("branch-03", b1.end_pose, [curve(60, -300), straight(240)])
    b4 = b.track("branch-04", b2.end_pose, [straight(500, -3)])
    b.point_switch("sw-06", b1.exit, b2.entry, b3.entry)
    b.link("lk-02", b2.exit, b4.entry)
    b.speed_section(
        "branch-60", 60, [("branch-01", 0, 1500, "both"), ("branch-02", 0, 800, "both")]
    )


def _freight_line(b: RailJsonBuilder, crossing: Pose) -> None:
    """The north–south freight line over the crossing, and its yard."""
    south = math.radians(-90.0)
    c0 = b.track("cross-00", Pose(crossing.east, crossing.north + 1500, south), [straight(500)])
    c1 = b.track("cross-01", c0.end_pose, [straight(1000, -4)])
    c2 = b.track("cross-02", Pose(crossing.east, crossing.north, south), [straight(1000, -4)])
    y1 = b.track("yard-01", c2.end_pose, [straight(600)])
    y2 = b.track("yard-02", c2.end_pose, [curve(100, -400), straight(400)])
    y3 = b.track("yard-03", y1.end_pose, [straight(400)])
    y4 = b.track("yard-04", y1.end_pose, [curve(60, 300), straight(340)])
    y5 = b.track("yard-05", y2.end_pose, [straight(300)])
    y6 = b.track("yard-06", y2.end_pose, [curve(60, -300), straight(240)])
    b.link("lk-03", c0.exit, c1.entry)
    b.point_switch("sw-07", c2.exit, y1.entry, y2.entry)
    b.point_switch("sw-10", y1.exit, y3.entry, y4.entry)
    b.point_switch("sw-11", y2.exit, y5.entry, y6.entry)


def long_line(sections: int, section_m: float) -> RailJsonBuilder:
    """``sections`` straight sections of ``section_m`` [m] in a chain of links, alternately
    stored forwards and backwards, gentle alternating gradients, an operational point ``start``
    50 m into the first and ``end`` 50 m before the end of the last."""
    b = RailJsonBuilder(45.0, 8.0)
    pose = Pose()
    handles = []
    for number in range(sections):
        gradient = 2.0 if number % 2 else -1.0
        handle = b.track(
            f"s{number:05d}", pose, [straight(section_m, gradient)], reverse=bool(number % 2)
        )
        handles.append(handle)
        pose = handle.end_pose
    for number in range(1, sections):
        b.link(f"l{number:05d}", handles[number - 1].exit, handles[number].entry)
        b.point_object("detectors", f"d{number:05d}", handles[number].id, 1.0)
    b.speed_section("line", 120, [(h.id, 0, section_m, "both") for h in handles])
    b.operational_point("start", "Start", [(handles[0].id, 50)])
    b.operational_point("end", "End", [(handles[-1].id, section_m - 50)])
    return b


def twin_tracks() -> RailJsonBuilder:
    """``in`` → point switch → two parallel 500 m tracks ``twin-b`` (80 km/h) and ``twin-a``
    (40 km/h) → point switch → ``out``; operational points ``west`` on ``in``, ``middle`` on
    both twins, ``b-platform`` on ``twin-b`` only, ``east`` on ``out``."""
    b = RailJsonBuilder(45.0, 8.0)
    track_in = b.track("in", Pose(), [straight(500)])
    twin_b = b.track("twin-b", track_in.end_pose, [straight(500)])
    twin_a = b.track("twin-a", track_in.end_pose, [straight(500)])
    track_out = b.track("out", twin_b.end_pose, [straight(500)])
    b.point_switch("sw-in", track_in.exit, twin_b.entry, twin_a.entry)
    b.point_switch("sw-out", track_out.entry, twin_b.exit, twin_a.exit)
    b.operational_point("west", "West", [("in", 100)])
    b.operational_point("middle", "Middle", [("twin-b", 250), ("twin-a", 250)])
    b.operational_point("b-platform", "B platform", [("twin-b", 300)])
    b.speed_section("twin-a-40", 40, [("twin-a", 0, 500, "both")])
    b.speed_section("twin-b-80", 80, [("twin-b", 0, 500, "both")])
    b.operational_point("east", "East", [("out", 100)])
    return b


if __name__ == "__main__":
    import sys

    sys.stdout.write(junction_valley().dumps())
