"""The import itself: read, search the path, add the margins, map everything onto a line."""

from __future__ import annotations

import json
import re
from collections import defaultdict
from collections.abc import Sequence
from typing import Any, get_args

from pydantic import BaseModel, ValidationError

from trackdb._exceptions import RailJsonError
from trackdb.railjson.graph import (
    TrackGraph,
    TrackPath,
    Waypoint,
    extension,
    find_path,
    merged,
    reversed_pieces,
)
from trackdb.railjson.models import RailJsonInfra, compact_geometry
from trackdb.railjson.places import (
    balise_groups,
    geodetic_polyline,
    stop_markers,
    stopping_point_id,
    unique_ids,
)
from trackdb.railjson.profiles import RANGE_TOLERANCE_M, line_profiles
from trackdb.schema import Line, StoppingPoint, parse_line

__all__ = [
    "DEFAULT_BALISE_SPACING_M",
    "DEFAULT_LINE_SPEED_KMH",
    "DEFAULT_MARGIN_M",
    "MAX_DOCUMENT_BYTES",
    "line_from_railjson",
    "read_infra",
]

MAX_DOCUMENT_BYTES = 64 * 1024 * 1024
"""Larger documents are refused before they are parsed [bytes]."""
DEFAULT_LINE_SPEED_KMH = 60.0
"""Line speed where no speed section applies [km/h]."""
DEFAULT_MARGIN_M = 300.0
"""Run-in before the origin and overrun after the destination, where the track goes on [m]."""
DEFAULT_BALISE_SPACING_M = 1000.0
"""Most distance between two balise groups (location references) [m]."""
_VERSION = re.compile(r"^3\.\d+(\.\d+)?$")


def read_infra(document: bytes | str) -> RailJsonInfra:
    """The document's parts we read, or the first problem as a :class:`RailJsonError`."""
    if len(document) > MAX_DOCUMENT_BYTES:
        raise RailJsonError(
            "$",
            f"document of {len(document)} bytes over the limit of {MAX_DOCUMENT_BYTES} bytes "
            f"({MAX_DOCUMENT_BYTES // 2**20} MiB)",
        )
    try:
        # Read with the standard parser, geometry compacted as it goes: a whole-document tree
        # (pydantic's JSON mode builds one) takes several times the document's size.
        tree = json.loads(document, object_hook=compact_geometry)
    except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError
        raise RailJsonError("$", f"not JSON: {exc}") from None
    if not isinstance(tree, dict):
        raise RailJsonError("$", f"a JSON object expected, not {type(tree).__name__}")
    version = tree.get("version")
    if not isinstance(version, str) or not _VERSION.match(version):
        raise RailJsonError(
            "$.version",
            f"unsupported RailJSON version {version!r}: this import reads versions 3.x",
        )
    return _validated(tree)


def _validated(tree: dict[str, Any]) -> RailJsonInfra:
    """The model of the tree; each long list is validated item by item, each dict replaced by
    its model as it goes, so that the tree and the models are never both whole in memory."""
    try:
        for name, field in RailJsonInfra.model_fields.items():
            items = tree.get(name)
            item_type = get_args(field.annotation)[0] if name != "version" else None
            if isinstance(items, list) and isinstance(item_type, type):
                _validate_items(name, items, item_type)
        return RailJsonInfra.model_validate(tree)
    except ValidationError as exc:
        first = exc.errors(include_url=False)[0]
        raise RailJsonError(_json_path(first["loc"]), first["msg"]) from None


def _validate_items(name: str, items: list[Any], item_type: type[BaseModel]) -> None:
    for index, item in enumerate(items):
        try:
            items[index] = item_type.model_validate(item)
        except ValidationError as exc:
            first = exc.errors(include_url=False)[0]
            raise RailJsonError(_json_path((name, index, *first["loc"])), first["msg"]) from None


def _json_path(location: Sequence[int | str]) -> str:
    path = "$"
    for part in location:
        path += f"[{part}]" if isinstance(part, int) else f".{part}"
    return path


def line_from_railjson(
    document: bytes | str,
    *,
    from_op: str,
    to_op: str,
    via: Sequence[str] = (),
    line_id: str,
    name: str | None = None,
    default_speed_kmh: float = DEFAULT_LINE_SPEED_KMH,
    speed_tag: str | None = None,
    margin_m: float = DEFAULT_MARGIN_M,
    balise_spacing_m: float = DEFAULT_BALISE_SPACING_M,
) -> Line:
    """The line from operational point ``from_op`` to ``to_op`` through ``via`` (ids of the
    document's operational points), named ``name`` (by default "ORIGIN – DESTINATION").

    ``default_speed_kmh`` [km/h] holds where no speed section applies; ``speed_tag`` picks the
    speed sections' limits for that tag where they have one (their default limit elsewhere);
    ``margin_m`` [m] of track is kept before the origin and after the destination where there
    is some; ``balise_spacing_m`` [m] is the most distance between two balise groups.

    Raises
    ------
    RailJsonError
        Anything in the document that keeps it from becoming a line, with its JSON path.
    """
    infra = read_infra(document)
    graph = TrackGraph(infra)
    names = [from_op, *via, to_op]
    waypoints = [_waypoint(infra, graph, op_id, role) for op_id, role in _roles(names)]
    path = find_path(graph, waypoints)
    path = _with_margins(graph, path, margin_m)
    length = sum(piece.length_m for piece in path.pieces)
    profiles = line_profiles(
        infra, graph, path.pieces, default_speed_kmh=default_speed_kmh, speed_tag=speed_tag
    )
    stops = _stopping_points(infra, graph, path, waypoints, length)
    detectors = _detector_chainages(infra, graph, path)
    origin = infra.operational_points[waypoints[0].op_index].name
    destination = infra.operational_points[waypoints[-1].op_index].name
    line_document = {
        "id": line_id,
        "name": (name or f"{origin} – {destination}")[:128],
        "length_m": length,
        "ring": False,
        "etcs_level": 2,
        "gradient_permille": profiles.gradient_permille,
        "curve_radius_m": profiles.curve_radius_m,
        "speed_limit_mps": profiles.speed_limit_mps,
        "balise_groups": balise_groups(detectors, length, balise_spacing_m),
        "stopping_points": stops,
        "stop_markers": stop_markers(stops),
        "geodetic": geodetic_polyline(infra, path.pieces, profiles.gradient_permille, length),
    }
    return parse_line(
        {
            key: [item.model_dump() for item in value] if isinstance(value, tuple) else value
            for key, value in line_document.items()
        }
    )


def _roles(names: Sequence[str]) -> list[tuple[str, str]]:
    roles = ["--from", *["--via"] * (len(names) - 2), "--to"]
    return list(zip(names, roles, strict=True))


def _waypoint(infra: RailJsonInfra, graph: TrackGraph, op_id: str, role: str) -> Waypoint:
    """An operational point the path must pass, its parts checked."""
    number = next((n for n, p in enumerate(infra.operational_points) if p.id == op_id), None)
    if number is None:
        raise RailJsonError(
            "$.operational_points", f"no operational point {op_id!r} (given with {role})"
        )
    where = f"$.operational_points[{number}]"
    point = infra.operational_points[number]
    if not point.parts:
        raise RailJsonError(f"{where}.parts", f"operational point {op_id!r} has no part")
    parts = tuple(
        _located(graph, f"{where}.parts[{index}]", part.track, part.position)
        for index, part in enumerate(point.parts)
    )
    return Waypoint(where, op_id, parts, number)


def _located(
    graph: TrackGraph, json_path: str, track_id: str, position: float
) -> tuple[int, float]:
    """(track, offset) of a point object, its position checked against the section's length."""
    track = graph.track(f"{json_path}.track", track_id)
    length = graph.lengths[track]
    if position > length + RANGE_TOLERANCE_M:
        raise RailJsonError(
            f"{json_path}.position",
            f"{position} m beyond the length {length} m of track section {track_id!r}",
        )
    return track, min(position, length)


def _with_margins(graph: TrackGraph, path: TrackPath, margin_m: float) -> TrackPath:
    """The path with up to ``margin_m`` of track before and after it."""
    used = {piece.track for piece in path.pieces}
    first, last = path.pieces[0], path.pieces[-1]
    before = reversed_pieces(
        extension(graph, first.track, not first.forward, first.start, margin_m, used)
    )
    after = extension(graph, last.track, last.forward, last.end, margin_m, used)
    run_in = sum(piece.length_m for piece in before)
    pieces = merged([*before, *path.pieces, *after])
    chainages = tuple(run_in + c for c in path.waypoint_chainages_m)
    return TrackPath(tuple(pieces), chainages, path.waypoint_parts)


def _along(path: TrackPath, points: Sequence[tuple[int, float]]) -> list[tuple[int, float]]:
    """(number, chainage [m]) of each point ``(track, offset)`` the path passes, ``number`` its
    index in ``points``, in the order passed (a point passed twice, twice)."""
    by_track: defaultdict[int, list[tuple[int, float]]] = defaultdict(list)
    for number, (track, offset) in enumerate(points):
        by_track[track].append((number, offset))
    found: list[tuple[int, float]] = []
    chainage = 0.0
    for piece in path.pieces:
        low, high = sorted((piece.start, piece.end))
        here = [
            (number, chainage + abs(offset - piece.start))
            for number, offset in by_track.get(piece.track, ())
            if low <= offset <= high
        ]
        found += sorted(here, key=lambda item: item[1])
        chainage += piece.length_m
    return found


def _stopping_points(
    infra: RailJsonInfra,
    graph: TrackGraph,
    path: TrackPath,
    waypoints: Sequence[Waypoint],
    length_m: float,
) -> tuple[StoppingPoint, ...]:
    """One per operational point on the line: where the path search put the origin, via and
    destination points; the first of its parts passed for the others."""
    parts = [
        (
            number,
            _located(graph, f"$.operational_points[{number}].parts[{index}]", p.track, p.position),
        )
        for number, point in enumerate(infra.operational_points)
        for index, p in enumerate(point.parts)
    ]
    chainage_of: dict[int, float] = {}
    for found, chainage in _along(path, [place for _, place in parts]):
        chainage_of.setdefault(parts[found][0], chainage)
    for waypoint, chainage in zip(waypoints, path.waypoint_chainages_m, strict=True):
        chainage_of[waypoint.op_index] = chainage
    placed = sorted(
        ((chainage, number) for number, chainage in chainage_of.items() if chainage < length_m)
    )
    ids = unique_ids([stopping_point_id(infra.operational_points[n].id) for _, n in placed])
    return tuple(
        StoppingPoint(
            id=stop_id, name=infra.operational_points[number].name[:128], position_m=chainage
        )
        for stop_id, (chainage, number) in zip(ids, placed, strict=True)
    )


def _detector_chainages(infra: RailJsonInfra, graph: TrackGraph, path: TrackPath) -> list[float]:
    points = [
        _located(graph, f"$.detectors[{n}]", d.track, d.position)
        for n, d in enumerate(infra.detectors)
    ]
    return [chainage for _, chainage in _along(path, points)]
