"""Our own pydantic models of the parts of an OSRD RailJSON infrastructure (3.x) that we read.

RailJSON is OSRD's exchange format for railway infrastructure (``osrd_schemas.infra`` in the
OpenRailAssociation/osrd repository). We read track sections (length, slopes, curves, geometry),
switches and their types (and the ``track_section_links`` of early 3.x documents), speed
sections, operational points and detectors; everything else (routes, signals, electrifications,
extensions we do not use...) is ignored, so a document from a newer 3.x with more fields still
reads. Offsets are metres from a track section's BEGIN; speeds are m/s; gradients ‰ (m/km);
geometry is a GeoJSON LineString of (longitude, latitude) in WGS 84 from BEGIN to END.

Ranges are checked where the import uses them (:mod:`trackdb.railjson.mapping`), so that an
error names the exact place (``$.track_sections[3].slopes[1]``); the models check types only.
"""

from __future__ import annotations

from array import array
from collections.abc import Iterator
from enum import StrEnum
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field

__all__ = [
    "ApplicableDirections",
    "Coordinates",
    "ApplicableRange",
    "Curve",
    "Detector",
    "Endpoint",
    "LineString",
    "OperationalPoint",
    "OperationalPointPart",
    "PortConnection",
    "RailJsonInfra",
    "Slope",
    "SpeedSection",
    "Switch",
    "SwitchType",
    "TrackEndpoint",
    "TrackSection",
    "TrackSectionLink",
    "compact_geometry",
]

Offset = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]
ObjectId = Annotated[str, Field(min_length=1)]


class _Model(BaseModel):
    # A foreign format: fields we do not read are ignored, not refused.
    model_config = ConfigDict(extra="ignore", frozen=True)


class Endpoint(StrEnum):
    BEGIN = "BEGIN"
    END = "END"


class ApplicableDirections(StrEnum):
    START_TO_STOP = "START_TO_STOP"
    STOP_TO_START = "STOP_TO_START"
    BOTH = "BOTH"


class Slope(_Model):
    gradient: Finite = Field(description="Gradient [‰], positive uphill from BEGIN to END")
    begin: Offset = Field(description="From BEGIN [m]")
    end: Offset = Field(description="From BEGIN [m]")


class Curve(_Model):
    radius: Finite = Field(description="Radius [m]; sign: see docs/trackdb.md (RailJSON import)")
    begin: Offset = Field(description="From BEGIN [m]")
    end: Offset = Field(description="From BEGIN [m]")


class Coordinates:
    """A LineString's positions as (longitude, latitude) [deg], two floats each in one array:
    the geometry of a large document in a fraction of the memory lists of floats take."""

    __slots__ = ("_values",)

    def __init__(self, values: array[float]) -> None:
        self._values = values

    def __len__(self) -> int:
        return len(self._values) // 2

    def __getitem__(self, index: int) -> tuple[float, float]:
        if not -len(self) <= index < len(self):
            raise IndexError(index)
        index %= len(self)
        return self._values[2 * index], self._values[2 * index + 1]

    def __iter__(self) -> Iterator[tuple[float, float]]:
        values = self._values
        return zip(values[0::2], values[1::2], strict=True)


def compact_geometry(node: dict[str, Any]) -> dict[str, Any]:
    """``json.loads``'s object hook: a LineString's coordinates become :class:`Coordinates` as
    the document is read, when each position is two or three numbers (else they stay as read,
    and the model reports where they are wrong)."""
    coordinates = node.get("coordinates")
    if node.get("type") != "LineString" or not isinstance(coordinates, list):
        return node
    values: array[float] = array("d")
    for position in coordinates:
        if not isinstance(position, list) or not 2 <= len(position) <= 3:
            return node
        longitude, latitude = position[0], position[1]
        if not all(type(x) in (float, int) for x in position):
            return node
        values.append(longitude)
        values.append(latitude)
    return node | {"coordinates": Coordinates(values)}


class LineString(_Model):
    """GeoJSON LineString: positions (longitude, latitude[, altitude]) [deg, deg, m]."""

    model_config = ConfigDict(arbitrary_types_allowed=True)

    type: str = "LineString"
    coordinates: (
        Coordinates | list[Annotated[tuple[float, ...], Field(min_length=2, max_length=3)]]
    ) = Field(min_length=2)


class TrackSection(_Model):
    id: ObjectId
    length: float = Field(gt=0.0, allow_inf_nan=False, description="[m]")
    slopes: list[Slope] = []
    curves: list[Curve] = []
    geo: LineString | None = None


class TrackEndpoint(_Model):
    endpoint: Endpoint
    track: ObjectId


class PortConnection(_Model):
    src: ObjectId
    dst: ObjectId


class SwitchType(_Model):
    """Ports and the groups of port connections a switch of this type can be set to."""

    id: ObjectId
    ports: list[ObjectId] = Field(min_length=1)
    groups: dict[str, list[PortConnection]]


class Switch(_Model):
    id: ObjectId
    switch_type: ObjectId
    ports: dict[str, TrackEndpoint]


class TrackSectionLink(_Model):
    """Early 3.x: a plain connection between two track ends (later a ``link`` switch)."""

    id: ObjectId
    src: TrackEndpoint
    dst: TrackEndpoint


class ApplicableRange(_Model):
    track: ObjectId
    begin: Offset
    end: Offset
    applicable_directions: ApplicableDirections = ApplicableDirections.BOTH


class SpeedSection(_Model):
    id: ObjectId
    speed_limit: float | None = Field(default=None, gt=0.0, allow_inf_nan=False, description="m/s")
    speed_limit_by_tag: dict[str, Annotated[float, Field(gt=0.0, allow_inf_nan=False)]] = {}
    track_ranges: list[ApplicableRange] = []


class OperationalPointPart(_Model):
    track: ObjectId
    position: Offset


class _IdentifierExtension(_Model):
    name: str = Field(min_length=1)


class _OperationalPointExtensions(_Model):
    identifier: _IdentifierExtension | None = None


class OperationalPoint(_Model):
    id: ObjectId
    parts: list[OperationalPointPart] = []
    extensions: _OperationalPointExtensions | None = None

    @property
    def name(self) -> str:
        """The ``identifier`` extension's name, else the id."""
        if self.extensions is not None and self.extensions.identifier is not None:
            return self.extensions.identifier.name
        return self.id


class Detector(_Model):
    id: ObjectId
    track: ObjectId
    position: Offset


class RailJsonInfra(_Model):
    """The document: ``version`` is checked by the import (3.x), not here."""

    version: str
    track_sections: list[TrackSection]
    switches: list[Switch] = []
    extended_switch_types: list[SwitchType] = []
    switch_types: list[SwitchType] = []
    track_section_links: list[TrackSectionLink] = []
    speed_sections: list[SpeedSection] = []
    operational_points: list[OperationalPoint] = []
    detectors: list[Detector] = []
