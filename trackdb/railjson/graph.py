"""The track-section graph of a RailJSON infrastructure, and the search for a line's path in it.

A train on a track section runs it forwards (entered at BEGIN, START_TO_STOP) or backwards
(entered at END, STOP_TO_START). At the end it leaves by, it may pass to another track end only
through a node that connects the two: a connection ``src``/``dst`` of one of the port groups of a
switch (connections are bidirectional; a point switch moves A↔B1 or A↔B2, never B1↔B2; a
crossing A1↔B1 and A2↔B2; a double slip any A to any B), or an early-3.x track section link.

:func:`find_path` searches the shortest path through the operational points given, in order,
without reversing: a Dijkstra search over (waypoints passed, track section, direction, offset),
keeping every predecessor that lies on a shortest path (to the millimetre). Among equally short
paths the rule is lexicographic: at the first place where they part, the one that passes the
next waypoint's part first, else the one entering the track section whose id sorts first
(forwards before backwards). The same rule picks the start among the first operational point's
parts.
"""

from __future__ import annotations

import heapq
import itertools
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass

from trackdb._exceptions import RailJsonError
from trackdb.railjson.models import Endpoint, PortConnection, RailJsonInfra, SwitchType

__all__ = [
    "BUILTIN_SWITCH_TYPES",
    "Piece",
    "TrackGraph",
    "TrackPath",
    "find_path",
    "merged",
]

TIE_TOLERANCE_M = 1e-3
"""Paths whose lengths differ by less than this are equally short [m]."""


def _type(type_id: str, ports: list[str], groups: dict[str, list[tuple[str, str]]]) -> SwitchType:
    return SwitchType(
        id=type_id,
        ports=ports,
        groups={
            name: [PortConnection(src=src, dst=dst) for src, dst in connections]
            for name, connections in groups.items()
        },
    )


BUILTIN_SWITCH_TYPES: dict[str, SwitchType] = {
    switch_type.id: switch_type
    for switch_type in (
        _type("link", ["A", "B"], {"STATIC": [("A", "B")]}),
        _type("point_switch", ["A", "B1", "B2"], {"A_B1": [("A", "B1")], "A_B2": [("A", "B2")]}),
        _type("crossing", ["A1", "B1", "A2", "B2"], {"STATIC": [("A1", "B1"), ("A2", "B2")]}),
        _type(
            "single_slip_switch",
            ["A1", "B1", "A2", "B2"],
            {"STATIC": [("A1", "B1"), ("A2", "B2")], "A1_B2": [("A1", "B2")]},
        ),
        _type(
            "double_slip_switch",
            ["A1", "B1", "A2", "B2"],
            {
                "A1_B1": [("A1", "B1")],
                "A1_B2": [("A1", "B2")],
                "A2_B1": [("A2", "B1")],
                "A2_B2": [("A2", "B2")],
            },
        ),
    )
}
"""OSRD's built-in switch types (RailJSON 3.4 on); a document's own types of the same id win."""


@dataclass(frozen=True, slots=True)
class Piece:
    """A stretch of one track section run in one direction, ``start`` → ``end`` offsets [m]."""

    track: int
    forward: bool
    start: float
    end: float

    @property
    def length_m(self) -> float:
        return abs(self.end - self.start)


@dataclass(frozen=True, slots=True)
class TrackPath:
    """The pieces run, in order, and the offset along the path of each waypoint reached [m]."""

    pieces: tuple[Piece, ...]
    waypoint_chainages_m: tuple[float, ...]
    waypoint_parts: tuple[int, ...]
    """Index of the part of each waypoint's operational point the path passes."""


# (track index, endpoint is END)
_End = tuple[int, bool]


class TrackGraph:
    """Track ends and the moves between them that the document's nodes allow."""

    def __init__(self, infra: RailJsonInfra) -> None:
        self.infra = infra
        self.index: dict[str, int] = {}
        for position, section in enumerate(infra.track_sections):
            if section.id in self.index:
                raise RailJsonError(
                    f"$.track_sections[{position}].id", f"duplicate track section {section.id!r}"
                )
            self.index[section.id] = position
        self.lengths = [section.length for section in infra.track_sections]
        self.ids = [section.id for section in infra.track_sections]
        self._moves: defaultdict[_End, set[_End]] = defaultdict(set)
        self._add_switches()
        for number, link in enumerate(infra.track_section_links):
            where = f"$.track_section_links[{number}]"
            self._connect(
                self._end(f"{where}.src", link.src.track, link.src.endpoint),
                self._end(f"{where}.dst", link.dst.track, link.dst.endpoint),
            )

    def track(self, json_path: str, track_id: str) -> int:
        """The index of a track section, or the error naming the reference."""
        try:
            return self.index[track_id]
        except KeyError:
            raise RailJsonError(json_path, f"no track section {track_id!r}") from None

    def moves(self, track: int, forward: bool) -> list[tuple[int, bool]]:
        """(track, forward) of each section a train leaving ``track`` may enter, sorted by id."""
        found = [(other, not at_end) for other, at_end in self._moves.get((track, forward), ())]
        return sorted(found, key=lambda move: (self.ids[move[0]], not move[1]))

    def _end(self, json_path: str, track_id: str, endpoint: Endpoint) -> _End:
        return self.track(f"{json_path}.track", track_id), endpoint is Endpoint.END

    def _connect(self, one: _End, other: _End) -> None:
        self._moves[one].add(other)
        self._moves[other].add(one)

    def _add_switches(self) -> None:
        types = dict(BUILTIN_SWITCH_TYPES)
        for name in ("switch_types", "extended_switch_types"):
            for switch_type in getattr(self.infra, name):
                types[switch_type.id] = switch_type
        for number, switch in enumerate(self.infra.switches):
            where = f"$.switches[{number}]"
            switch_type = types.get(switch.switch_type)
            if switch_type is None:
                raise RailJsonError(
                    f"{where}.switch_type",
                    f"unknown switch type {switch.switch_type!r} (known: {', '.join(types)})",
                )
            for group, connections in switch_type.groups.items():
                for connection in connections:
                    ends = []
                    for port in (connection.src, connection.dst):
                        endpoint = switch.ports.get(port)
                        if endpoint is None:
                            raise RailJsonError(
                                f"{where}.ports",
                                f"no port {port!r}, which group {group!r} of switch type "
                                f"{switch_type.id!r} connects",
                            )
                        ends.append(
                            self._end(f"{where}.ports.{port}", endpoint.track, endpoint.endpoint)
                        )
                    self._connect(ends[0], ends[1])


# A search node: (waypoints passed - 1, track, forward, offset)
_Node = tuple[int, int, bool, float]


@dataclass(frozen=True, slots=True)
class Waypoint:
    """An operational point to pass: its parts as (track, offset), and where it is named."""

    json_path: str
    op_id: str
    parts: tuple[tuple[int, float], ...]
    op_index: int
    """Its index in the document's ``operational_points``."""


def find_path(graph: TrackGraph, waypoints: Sequence[Waypoint]) -> TrackPath:
    """The shortest path from the first waypoint through the others in order (see the module
    docstring for the rule among equals); :class:`RailJsonError` when there is none."""
    search = _Search(graph, waypoints)
    targets = search.run()
    if not targets:
        raise RailJsonError(
            waypoints[-1].json_path,
            "no path from "
            + " via ".join(repr(w.op_id) for w in waypoints[:-1])
            + f" to {waypoints[-1].op_id!r} along the tracks and switches (without reversing)",
        )
    path = search.chosen_path(targets)
    if not path.pieces:
        raise RailJsonError(
            waypoints[-1].json_path,
            f"the path from {waypoints[0].op_id!r} to {waypoints[-1].op_id!r} has no length",
        )
    return path


class _Search:
    def __init__(self, graph: TrackGraph, waypoints: Sequence[Waypoint]) -> None:
        self.graph = graph
        self.waypoints = waypoints
        self.last = len(waypoints) - 1
        self.parts_on: list[defaultdict[int, list[float]]] = []
        for waypoint in waypoints:
            by_track: defaultdict[int, list[float]] = defaultdict(list)
            for track, offset in waypoint.parts:
                by_track[track].append(offset)
            self.parts_on.append(by_track)
        self.distance: dict[_Node, float] = {}
        self.predecessors: dict[_Node, list[_Node]] = {}

    def successors(self, node: _Node) -> list[tuple[_Node, float]]:
        layer, track, forward, offset = node
        found: list[tuple[_Node, float]] = []
        if layer < self.last:
            for part in sorted(self.parts_on[layer + 1].get(track, ()), reverse=not forward):
                ahead = part - offset if forward else offset - part
                if ahead >= 0.0:
                    found.append(((layer + 1, track, forward, part), ahead))
        remaining = self.graph.lengths[track] - offset if forward else offset
        for other, other_forward in self.graph.moves(track, forward):
            entry = 0.0 if other_forward else self.graph.lengths[other]
            found.append(((layer, other, other_forward, entry), remaining))
        return found

    def run(self) -> list[_Node]:
        counter = itertools.count()
        heap: list[tuple[float, int, _Node]] = []
        for track, offset in self.waypoints[0].parts:
            for forward in (True, False):
                node = (0, track, forward, offset)
                self.distance[node] = 0.0
                self.predecessors[node] = []
                heapq.heappush(heap, (0.0, next(counter), node))
        settled: set[_Node] = set()
        best = float("inf")
        while heap:
            cost, _, node = heapq.heappop(heap)
            if cost > best + TIE_TOLERANCE_M:
                break
            if node in settled:
                continue
            settled.add(node)
            if node[0] == self.last:
                best = min(best, cost)
                continue
            for following, step in self.successors(node):
                self._relax(node, following, cost + step, heap, counter)
        return sorted(
            (
                n
                for n in settled
                if n[0] == self.last and self.distance[n] <= best + TIE_TOLERANCE_M
            ),
            key=self._key,
        )

    def _relax(
        self,
        node: _Node,
        following: _Node,
        cost: float,
        heap: list[tuple[float, int, _Node]],
        counter: itertools.count[int],
    ) -> None:
        known = self.distance.get(following)
        if known is None or cost < known - TIE_TOLERANCE_M:
            self.distance[following] = cost
            self.predecessors[following] = [node]
            heapq.heappush(heap, (cost, next(counter), following))
        elif cost <= known + TIE_TOLERANCE_M:
            self.predecessors[following].append(node)
            if cost < known:
                self.distance[following] = cost

    def _key(self, node: _Node) -> tuple[int, str, bool, float]:
        layer, track, forward, offset = node
        return (-layer, self.graph.ids[track], not forward, offset)

    def chosen_path(self, targets: list[_Node]) -> TrackPath:
        on_shortest: set[_Node] = set()
        stack = list(targets)
        following: defaultdict[_Node, list[_Node]] = defaultdict(list)
        while stack:
            node = stack.pop()
            if node in on_shortest:
                continue
            on_shortest.add(node)
            for previous in self.predecessors[node]:
                following[previous].append(node)
                stack.append(previous)
        starts = [n for n in on_shortest if not self.predecessors[n]]
        node = min(starts, key=self._key)
        walk = [node]
        target_set = set(targets)
        while node not in target_set:
            node = min(following[node], key=self._key)
            walk.append(node)
        return self._as_path(walk)

    def _as_path(self, walk: list[_Node]) -> TrackPath:
        pieces: list[Piece] = []
        chainages: list[float] = [0.0]
        parts: list[int] = [self._part_index(0, walk[0])]
        travelled = 0.0
        for node, following in itertools.pairwise(walk):
            layer, track, forward, offset = node
            if following[0] > layer:  # the next waypoint, on the same track
                end = following[3]
            else:
                end = self.graph.lengths[track] if forward else 0.0
            piece = Piece(track, forward, offset, end)
            if piece.length_m > 0.0:
                pieces.append(piece)
            travelled += piece.length_m
            if following[0] > layer:
                chainages.append(travelled)
                parts.append(self._part_index(following[0], following))
        return TrackPath(tuple(merged(pieces)), tuple(chainages), tuple(parts))

    def _part_index(self, layer: int, node: _Node) -> int:
        return self.waypoints[layer].parts.index((node[1], node[3]))


def merged(pieces: list[Piece]) -> list[Piece]:
    """Consecutive pieces of one track in one direction become one."""
    merged: list[Piece] = []
    for piece in pieces:
        last = merged[-1] if merged else None
        if (
            last is not None
            and last.track == piece.track
            and last.forward == piece.forward
            and last.end == piece.start
        ):
            merged[-1] = Piece(piece.track, piece.forward, last.start, piece.end)
        else:
            merged.append(piece)
    return merged


def extension(
    graph: TrackGraph, track: int, forward: bool, offset: float, length_m: float, avoid: set[int]
) -> list[Piece]:
    """Up to ``length_m`` [m] of track ahead of ``offset`` on ``track`` run in that direction,
    continuing at each node into the section whose id sorts first among those not in ``avoid``;
    shorter where the track ends."""
    pieces: list[Piece] = []
    left = length_m
    while left > 0.0:
        end = graph.lengths[track] if forward else 0.0
        run = min(left, abs(end - offset))
        if run > 0.0:
            pieces.append(Piece(track, forward, offset, offset + run if forward else offset - run))
            left -= run
        if left <= 0.0:
            break
        moves = [move for move in graph.moves(track, forward) if move[0] not in avoid]
        if not moves:
            break
        track, forward = moves[0]
        avoid = avoid | {track}
        offset = 0.0 if forward else graph.lengths[track]
    return pieces


def reversed_pieces(pieces: list[Piece]) -> list[Piece]:
    """The same stretch of track run the other way."""
    return [Piece(p.track, not p.forward, p.end, p.start) for p in reversed(pieces)]
