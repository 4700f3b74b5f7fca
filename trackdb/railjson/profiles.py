"""Profiles along a RailJSON path: gradients, curves and speeds from track-section ranges.

Each track section holds its ranges in its own offsets (from BEGIN). A piece of the path runs a
section forwards or backwards; its ranges are mapped onto the line's chainage, mirrored when
backwards, and the values that depend on the direction change sign there (a slope climbing from
BEGIN to END falls the other way; a curve to the right seen from BEGIN turns left seen from END).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass

from protocol.units import MPS_PER_KMH
from trackdb._exceptions import RailJsonError
from trackdb.railjson.graph import Piece, TrackGraph
from trackdb.railjson.models import ApplicableDirections, RailJsonInfra
from trackdb.schema import ProfileSection

__all__ = [
    "MAX_SPEED_MPS",
    "MIN_CURVE_RADIUS_M",
    "RANGE_TOLERANCE_M",
    "LineProfiles",
    "line_profiles",
]

RANGE_TOLERANCE_M = 1e-3
"""A range may pass its section's length by this much (rounding in the source) [m]."""
MIN_CURVE_RADIUS_M = 50.0
"""Our line schema's smallest curve radius [m]."""
MAX_SPEED_MPS = 150.0
"""Our line schema's highest speed [m/s]."""

# (begin, end, value) in a section's offsets [m]
_Range = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class LineProfiles:
    gradient_permille: tuple[ProfileSection, ...]
    curve_radius_m: tuple[ProfileSection, ...]
    speed_limit_mps: tuple[ProfileSection, ...]


class _Profile:
    """Sections appended in chainage order; equal neighbours merge, and one that starts within a
    micrometre of the previous one's end starts exactly there (no gap from rounding)."""

    def __init__(self) -> None:
        self.sections: list[ProfileSection] = []

    def add(self, start_m: float, end_m: float, value: float | None) -> None:
        if self.sections and abs(start_m - self.sections[-1].end_m) < 1e-6:
            start_m = self.sections[-1].end_m
        if end_m <= start_m or value is None:
            return
        last = self.sections[-1] if self.sections else None
        if last is not None and last.value == value and last.end_m == start_m:
            self.sections[-1] = ProfileSection(start_m=last.start_m, end_m=end_m, value=value)
        else:
            self.sections.append(ProfileSection(start_m=start_m, end_m=end_m, value=value))


def line_profiles(
    infra: RailJsonInfra,
    graph: TrackGraph,
    pieces: Sequence[Piece],
    *,
    default_speed_kmh: float,
    speed_tag: str | None,
) -> LineProfiles:
    """The gradient [‰], signed curve radius [m] and speed [m/s] profiles along ``pieces``."""
    speeds = _speed_ranges(infra, graph, speed_tag)
    gradient, curves, speed = _Profile(), _Profile(), _Profile()
    chainage = 0.0
    for piece in pieces:
        where = f"$.track_sections[{piece.track}]"
        section = infra.track_sections[piece.track]
        slopes = _checked(
            f"{where}.slopes",
            [(s.begin, s.end, s.gradient) for s in section.slopes],
            section.length,
        )
        radii = _checked(
            f"{where}.curves", [(c.begin, c.end, c.radius) for c in section.curves], section.length
        )
        for number, (_, _, radius) in enumerate(radii):
            if radius != 0.0 and abs(radius) < MIN_CURVE_RADIUS_M:
                raise RailJsonError(
                    f"{where}.curves[{number}].radius",
                    f"radius {radius} m below the {MIN_CURVE_RADIUS_M:.0f} m a line may have",
                )
        sign = 1.0 if piece.forward else -1.0
        _map(gradient, piece, chainage, [(b, e, sign * g) for b, e, g in slopes], 0.0, False)
        # RailJSON (as railML) counts a radius positive curving right seen from BEGIN; ours is
        # positive turning left in the direction of travel; 0 is straight.
        turns = [(b, e, -sign * r) for b, e, r in radii if r != 0.0]
        _map(curves, piece, chainage, turns, None, False)
        direction = speeds[(piece.track, piece.forward)]
        _map(speed, piece, chainage, direction, default_speed_kmh * MPS_PER_KMH, True)
        chainage += piece.length_m
    return LineProfiles(tuple(gradient.sections), tuple(curves.sections), tuple(speed.sections))


def _map(
    profile: _Profile,
    piece: Piece,
    chainage_m: float,
    ranges: list[_Range],
    default: float | None,
    overlap: bool,
) -> None:
    """Append ``ranges`` seen along ``piece``, which starts at ``chainage_m``; where several
    apply (``overlap``) the least value holds; where none, ``default``."""
    low, high = sorted((piece.start, piece.end))
    cuts = {low, high}
    for begin, end, _ in ranges:
        cuts.update(x for x in (begin, end) if low < x < high)
    ordered = sorted(cuts)
    steps = list(zip(ordered, ordered[1:], strict=False))
    if not piece.forward:
        steps.reverse()
    for first, second in steps:
        values = [value for begin, end, value in ranges if begin <= first and second <= end]
        value = (min(values) if overlap else values[0]) if values else default
        if piece.forward:
            start, end = chainage_m + (first - piece.start), chainage_m + (second - piece.start)
        else:
            start, end = chainage_m + (piece.start - second), chainage_m + (piece.start - first)
        profile.add(start, end, value)


def _checked(json_path: str, ranges: list[_Range], length_m: float) -> list[_Range]:
    """The ranges sorted, each inside the section, none overlapping another."""
    ordered = sorted(enumerate(ranges), key=lambda item: item[1][0])
    checked: list[_Range] = []
    for number, (begin, end, value) in ordered:
        _check_range(f"{json_path}[{number}]", begin, end, length_m)
        if checked and begin < checked[-1][1] - RANGE_TOLERANCE_M:
            raise RailJsonError(
                f"{json_path}[{number}]",
                f"range {begin}..{end} m overlaps another that ends at {checked[-1][1]} m",
            )
        checked.append((begin, min(end, length_m), value))
    return checked


def _check_range(json_path: str, begin: float, end: float, length_m: float) -> None:
    if end <= begin:
        raise RailJsonError(json_path, f"empty or inverted range: begin {begin} m, end {end} m")
    if end > length_m + RANGE_TOLERANCE_M:
        raise RailJsonError(
            json_path, f"range {begin}..{end} m beyond the track section's length {length_m} m"
        )


def _speed_ranges(
    infra: RailJsonInfra, graph: TrackGraph, speed_tag: str | None
) -> defaultdict[tuple[int, bool], list[_Range]]:
    """Speed limits [m/s] by (track, forward): the tag's limit where the section has one for
    ``speed_tag``, else its default ``speed_limit``; sections with neither do not apply."""
    found: defaultdict[tuple[int, bool], list[_Range]] = defaultdict(list)
    for number, section in enumerate(infra.speed_sections):
        where = f"$.speed_sections[{number}]"
        limit = section.speed_limit
        if speed_tag is not None and speed_tag in section.speed_limit_by_tag:
            limit = section.speed_limit_by_tag[speed_tag]
        if limit is None:
            continue
        if limit > MAX_SPEED_MPS:
            raise RailJsonError(
                f"{where}.speed_limit",
                f"{limit} m/s above the {MAX_SPEED_MPS:.0f} m/s a line allows",
            )
        for part, track_range in enumerate(section.track_ranges):
            track = graph.track(f"{where}.track_ranges[{part}].track", track_range.track)
            _check_range(
                f"{where}.track_ranges[{part}]",
                track_range.begin,
                track_range.end,
                graph.lengths[track],
            )
            applies = track_range.applicable_directions
            for forward in (True, False):
                wanted = (
                    ApplicableDirections.START_TO_STOP
                    if forward
                    else ApplicableDirections.STOP_TO_START
                )
                if applies in (ApplicableDirections.BOTH, wanted):
                    found[(track, forward)].append((track_range.begin, track_range.end, limit))
    return found
