"""Places along a RailJSON path: stopping points, precision-stop markers, balise groups, and
the geodetic polyline.

- Stopping points: one per operational point with a part on the line, at the first of its parts
  the line passes (the origin, via and destination points where the path search placed them).
  Ids follow :func:`stopping_point_id`.
- A precision-stop marker ``<stop id>-marker`` lies :data:`STOP_MARKER_BEFORE_M` before each
  stopping point, as on ``bologna-ring``.
- Balise groups (Level 2: location references only, each linked to the next): one at each
  detector on the line, none within :data:`MIN_GROUP_SPACING_M` of the previous, then more,
  evenly spaced, wherever two groups (or the line's start and the first) lie further apart
  than the spacing asked for.
- The polyline: the track sections' geometry, each mapped onto its section's length in
  proportion (RailJSON geometry need not measure exactly ``length``), plus a point at each
  change of gradient; altitude integrated from the gradient profile, the line's lowest point at
  0 m (RailJSON gives slopes, not heights).
"""

from __future__ import annotations

import hashlib
import itertools
import math
import re
import unicodedata
from collections.abc import Sequence

from trackdb._exceptions import RailJsonError
from trackdb.railjson.graph import Piece
from trackdb.railjson.models import RailJsonInfra
from trackdb.schema import (
    BaliseGroup,
    GeoPoint,
    Link,
    LinkingPacket,
    ProfileSection,
    StopMarker,
    StoppingPoint,
)
from trackdb.seed_lines import STOP_MARKER_BEFORE_M

__all__ = [
    "MIN_GROUP_SPACING_M",
    "STOP_ID_MAX_LENGTH",
    "balise_groups",
    "geodetic_polyline",
    "stop_markers",
    "stopping_point_id",
]

MIN_GROUP_SPACING_M = 50.0
"""A detector this close after the previous balise group gets no group of its own [m]."""
STOP_ID_MAX_LENGTH = 57
"""Room for the ``-marker`` suffix within our 64-character identifiers."""
_EARTH_RADIUS_M = 6_371_000.0


def stopping_point_id(op_id: str) -> str:
    """Our identifier for an operational point's id: accents dropped, lower case, every run of
    other characters than ``a-z 0-9 _ -`` a ``-``, leading ``-``/``_`` and trailing ``-``
    removed; longer than 57 characters (or empty), cut to 48 and ended by ``-`` and the first 8
    hexadecimal digits of the original id's SHA-256."""
    text = unicodedata.normalize("NFKD", op_id)
    text = "".join(c for c in text if not unicodedata.combining(c)).lower()
    text = re.sub(r"[^a-z0-9_-]+", "-", text).lstrip("-_").rstrip("-")
    if not text or len(text) > STOP_ID_MAX_LENGTH:
        digest = hashlib.sha256(op_id.encode()).hexdigest()[:8]
        text = f"{text[:48].rstrip('-_')}-{digest}" if text else f"op-{digest}"
    return text


def unique_ids(ids: Sequence[str]) -> list[str]:
    """Repeats of an id (two operational points that map to one) get ``-2``, ``-3``... in order."""
    seen: dict[str, int] = {}
    unique = []
    for item in ids:
        count = seen.get(item, 0) + 1
        seen[item] = count
        unique.append(item if count == 1 else f"{item[: STOP_ID_MAX_LENGTH - 4]}-{count}")
    return unique


def stop_markers(stops: Sequence[StoppingPoint]) -> tuple[StopMarker, ...]:
    markers: list[StopMarker] = []
    for stop in sorted(stops, key=lambda s: s.position_m):
        position = stop.position_m - STOP_MARKER_BEFORE_M
        if position >= 0.0 and (not markers or position > markers[-1].position_m):
            markers.append(StopMarker(id=f"{stop.id}-marker", position_m=position))
    return tuple(markers)


def balise_groups(
    detector_chainages_m: Sequence[float], length_m: float, spacing_m: float
) -> tuple[BaliseGroup, ...]:
    """Groups at the detectors, and evenly between them where they are over ``spacing_m`` apart."""
    at_detectors: list[float] = []
    for chainage in sorted(detector_chainages_m):
        if 0.0 <= chainage < length_m and (
            not at_detectors or chainage - at_detectors[-1] >= MIN_GROUP_SPACING_M
        ):
            at_detectors.append(chainage)
    positions: list[float] = []
    previous = 0.0
    for chainage in [*at_detectors, length_m]:
        gap = chainage - previous
        extra = math.ceil(gap / spacing_m) - 1 if gap > spacing_m else 0
        positions += [previous + gap * (k + 1) / (extra + 1) for k in range(extra)]
        if chainage < length_m:
            positions.append(chainage)
        previous = chainage
    groups: list[BaliseGroup] = []
    for number, position in enumerate(positions):
        packets: tuple[LinkingPacket, ...] = ()
        if number + 1 < len(positions):
            link = Link(distance_m=positions[number + 1] - position, balise_group_id=number + 2)
            packets = (LinkingPacket(links=(link,)),)
        groups.append(BaliseGroup(id=number + 1, position_m=position, packets=packets))
    return tuple(groups)


def geodetic_polyline(
    infra: RailJsonInfra,
    pieces: Sequence[Piece],
    gradients: Sequence[ProfileSection],
    length_m: float,
) -> tuple[GeoPoint, ...]:
    """The line's polyline, or none when a section on the path has no geometry."""
    points: list[tuple[float, float, float]] = []  # chainage, lon, lat
    chainage = 0.0
    for piece in pieces:
        for at, lon, lat in _piece_points(infra, piece):
            where = chainage + at
            if not points or where > points[-1][0] + 1e-6:
                points.append((where, lon, lat))
        chainage += piece.length_m
    if not points:
        return ()
    points[0] = (0.0, points[0][1], points[0][2])
    points[-1] = (length_m, points[-1][1], points[-1][2])
    points = _with_gradient_changes(points, gradients)
    altitudes = _altitudes([p[0] for p in points], gradients)
    lowest = min(altitudes)
    return tuple(
        GeoPoint(chainage_m=c, latitude_deg=lat, longitude_deg=lon, altitude_m=alt - lowest)
        for (c, lon, lat), alt in zip(points, altitudes, strict=True)
    )


def _piece_points(infra: RailJsonInfra, piece: Piece) -> list[tuple[float, float, float]]:
    """(distance from the piece's start [m], lon, lat) of the piece's ends and the vertices of
    its section's geometry between them; none when the section has no geometry."""
    section = infra.track_sections[piece.track]
    if section.geo is None:
        return []
    coordinates = [(position[0], position[1]) for position in section.geo.coordinates]
    for number, position in enumerate(coordinates):
        if not (-180.0 <= position[0] <= 180.0 and -90.0 <= position[1] <= 90.0):
            raise RailJsonError(
                f"$.track_sections[{piece.track}].geo.coordinates[{number}]",
                f"({position[0]}, {position[1]}) is not a WGS 84 longitude and latitude",
            )
    along = [0.0]
    for first, second in itertools.pairwise(coordinates):
        along.append(along[-1] + _distance_m(first, second))
    scale = section.length / along[-1] if along[-1] > 0.0 else 0.0
    offsets = [d * scale for d in along]
    low, high = sorted((piece.start, piece.end))
    chosen = [(low, *_at(coordinates, offsets, low))]
    chosen += [(x, p[0], p[1]) for x, p in zip(offsets, coordinates, strict=True) if low < x < high]
    chosen.append((high, *_at(coordinates, offsets, high)))
    if not piece.forward:
        chosen.reverse()
    return [(abs(x - piece.start), lon, lat) for x, lon, lat in chosen]


def _distance_m(first: tuple[float, ...], second: tuple[float, ...]) -> float:
    mean_latitude = math.radians((first[1] + second[1]) / 2.0)
    east = math.radians(second[0] - first[0]) * math.cos(mean_latitude)
    north = math.radians(second[1] - first[1])
    return _EARTH_RADIUS_M * math.hypot(east, north)


def _at(
    coordinates: Sequence[tuple[float, ...]], offsets: Sequence[float], offset: float
) -> tuple[float, float]:
    """(lon, lat) at an offset [m] of the section, linear between vertices."""
    for index in range(1, len(offsets)):
        if offset <= offsets[index] or index == len(offsets) - 1:
            span = offsets[index] - offsets[index - 1]
            share = 0.0 if span <= 0.0 else min(max((offset - offsets[index - 1]) / span, 0.0), 1.0)
            first, second = coordinates[index - 1], coordinates[index]
            return (
                first[0] + share * (second[0] - first[0]),
                first[1] + share * (second[1] - first[1]),
            )
    return coordinates[0][0], coordinates[0][1]


def _with_gradient_changes(
    points: list[tuple[float, float, float]], gradients: Sequence[ProfileSection]
) -> list[tuple[float, float, float]]:
    """A point added (interpolated) at each change of gradient, so altitude is exact there."""
    wanted = sorted({s.start_m for s in gradients[1:]} - {p[0] for p in points})
    merged: list[tuple[float, float, float]] = []
    index = 0
    for point in points:
        while index < len(wanted) and wanted[index] < point[0]:
            previous = merged[-1]
            share = (wanted[index] - previous[0]) / (point[0] - previous[0])
            merged.append(
                (
                    wanted[index],
                    previous[1] + share * (point[1] - previous[1]),
                    previous[2] + share * (point[2] - previous[2]),
                )
            )
            index += 1
        merged.append(point)
    return merged


def _altitudes(chainages: Sequence[float], gradients: Sequence[ProfileSection]) -> list[float]:
    """Altitude [m] at increasing chainages, from 0 at chainage 0, integrating the gradient."""
    altitudes = []
    section_index = 0
    base = 0.0  # altitude at the start of gradients[section_index]
    for chainage in chainages:
        while section_index + 1 < len(gradients) and gradients[section_index].end_m <= chainage:
            section = gradients[section_index]
            base += section.value / 1000.0 * (section.end_m - section.start_m)
            section_index += 1
        section = gradients[section_index]
        altitudes.append(base + section.value / 1000.0 * (chainage - section.start_m))
    return altitudes
