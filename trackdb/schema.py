"""The line schema: profiles along chainage, balise groups, stopping points, geodetic polyline.

A line is a set of piecewise-constant profiles over ``[0, length_m)``:

- gradient [‰, positive uphill in the direction of increasing chainage], covering the line;
- curves: signed radius [m, positive turning left, negative turning right], straight elsewhere;
- the static speed profile (SSP) [m/s], covering the line;
- temporary speed restrictions (TSR) [m/s] over ranges.

Balise groups carry ETCS packets (movement authority, SSP, gradient, level transition, linking)
with distances counted from the group, as on the track. Stopping points name where journeys stop.
The geodetic polyline gives latitude, longitude and altitude at increasing chainages; it is used
to emulate GPS and to project GPS fixes back to chainage. On a ring line chainage wraps at the
line's length. The SHA-256 of the canonical JSON is the line's version.

Abbreviations: SSP (static speed profile), TSR (temporary speed restriction), MA (movement
authority), EoA (end of authority), NID_BG (balise group identity), GPS (satellite position).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections import Counter
from collections.abc import Mapping
from enum import StrEnum
from typing import Annotated, Any, Literal, Self

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from trackdb._exceptions import LineValidationError

__all__ = [
    "SCHEMA_VERSION",
    "BaliseGroup",
    "BalisePacket",
    "GeoPoint",
    "GradientPacket",
    "Identifier",
    "LevelTransitionPacket",
    "Line",
    "LineValidationError",
    "Link",
    "LinkReaction",
    "LinkingPacket",
    "MovementAuthorityPacket",
    "PacketSection",
    "ProfileSection",
    "StaticSpeedProfilePacket",
    "StopMarker",
    "StoppingPoint",
    "TemporarySpeedRestriction",
    "line_json_schema",
    "parse_line",
]

SCHEMA_VERSION = 1

Identifier = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[a-z0-9][a-z0-9_-]*$")]
Metres = Annotated[float, Field(allow_inf_nan=False)]
NonNegativeMetres = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
PositiveSpeed = Annotated[float, Field(gt=0.0, le=150.0, allow_inf_nan=False)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ProfileSection(_Model):
    """A constant value over ``[start_m, end_m)``."""

    start_m: NonNegativeMetres = Field(description="Section start, chainage [m]")
    end_m: float = Field(gt=0.0, allow_inf_nan=False, description="Section end, chainage [m]")
    value: float = Field(allow_inf_nan=False, description="Value, in the profile's unit")


class TemporarySpeedRestriction(_Model):
    """A TSR: a speed limit [m/s] over ``[start_m, end_m)`` until revoked."""

    id: Identifier
    start_m: NonNegativeMetres = Field(description="Start, chainage [m]")
    end_m: float = Field(gt=0.0, allow_inf_nan=False, description="End, chainage [m]")
    speed_mps: PositiveSpeed = Field(description="Speed limit [m/s]")


class PacketSection(_Model):
    """One step of a packet profile: from ``distance_m`` after the group on, ``value`` holds."""

    distance_m: NonNegativeMetres = Field(description="Distance from the balise group [m]")
    value: float = Field(allow_inf_nan=False, description="Value, in the packet's unit")


class MovementAuthorityPacket(_Model):
    """Level 1 movement authority (packet 12, reduced): EoA, danger point, overlap."""

    type: Literal["movement_authority"] = "movement_authority"
    end_of_authority_m: float = Field(gt=0.0, allow_inf_nan=False, description="EoA distance [m]")
    danger_point_m: NonNegativeMetres = Field(default=0.0, description="EoA to danger point [m]")
    overlap_m: NonNegativeMetres = Field(default=0.0, description="EoA to end of overlap [m]")
    release_speed_mps: float | None = Field(
        default=None, ge=0.0, le=20.0, allow_inf_nan=False, description="Release speed [m/s]"
    )


class StaticSpeedProfilePacket(_Model):
    """Static speed profile (packet 27, reduced): speeds [m/s] from distances ahead."""

    type: Literal["static_speed_profile"] = "static_speed_profile"
    sections: tuple[PacketSection, ...] = Field(min_length=1)
    length_m: float = Field(gt=0.0, allow_inf_nan=False, description="Profile length [m]")


class GradientPacket(_Model):
    """Gradient profile (packet 21, reduced): gradients [‰] from distances ahead."""

    type: Literal["gradient"] = "gradient"
    sections: tuple[PacketSection, ...] = Field(min_length=1)
    length_m: float = Field(gt=0.0, allow_inf_nan=False, description="Profile length [m]")


class LevelTransitionPacket(_Model):
    """Level transition order (packet 41, reduced)."""

    type: Literal["level_transition"] = "level_transition"
    distance_m: NonNegativeMetres = Field(description="Distance to the transition [m]")
    level: Literal[1, 2]


class LinkReaction(StrEnum):
    TRAIN_TRIP = "train_trip"
    SERVICE_BRAKE = "service_brake"
    NO_REACTION = "no_reaction"


class Link(_Model):
    distance_m: float = Field(gt=0.0, allow_inf_nan=False, description="Distance to the group [m]")
    balise_group_id: int = Field(ge=0, lt=2**14, description="NID_BG of the linked group")
    reaction: LinkReaction = LinkReaction.SERVICE_BRAKE
    location_accuracy_m: NonNegativeMetres = Field(default=5.0, description="Q_LOCACC [m]")


class LinkingPacket(_Model):
    """Linking (packet 5, reduced): the groups expected next."""

    type: Literal["linking"] = "linking"
    links: tuple[Link, ...] = Field(min_length=1)


BalisePacket = Annotated[
    MovementAuthorityPacket
    | StaticSpeedProfilePacket
    | GradientPacket
    | LevelTransitionPacket
    | LinkingPacket,
    Field(discriminator="type"),
]


class BaliseGroup(_Model):
    """A balise group at a chainage, read in the direction of increasing chainage."""

    id: int = Field(ge=0, lt=2**14, description="NID_BG")
    position_m: NonNegativeMetres = Field(description="Chainage [m]")
    packets: tuple[BalisePacket, ...] = ()


class StoppingPoint(_Model):
    """A place where journeys may stop, and how precisely."""

    id: Identifier
    name: str = Field(min_length=1, max_length=128)
    position_m: NonNegativeMetres = Field(description="Stopping chainage of the front end [m]")
    platform_length_m: float = Field(default=100.0, gt=0.0, le=1000.0, allow_inf_nan=False)
    stopping_tolerance_m: float = Field(
        default=0.5, ge=0.1, le=100.0, allow_inf_nan=False, description="± tolerance [m]"
    )


class StopMarker(_Model):
    """A precision-stop marker: a passive tag between the rails, before a stopping point, that
    the vehicle's short-range reader detects as the front end passes over it. Its location is a
    position fix of a few centimetres where a stop needs one (the balise groups' ±1 m and the
    GNSS's decimetres are not enough for ±0.5 m), as metro ATOs' precision-stop transponders."""

    id: Identifier
    position_m: NonNegativeMetres = Field(description="Chainage of the tag's centre [m]")


class GeoPoint(_Model):
    """A point of the geodetic polyline (WGS 84)."""

    chainage_m: NonNegativeMetres
    latitude_deg: float = Field(ge=-90.0, le=90.0, allow_inf_nan=False)
    longitude_deg: float = Field(ge=-180.0, le=180.0, allow_inf_nan=False)
    altitude_m: float = Field(ge=-500.0, le=9000.0, allow_inf_nan=False)


class Line(_Model):
    """A railway line as the onboard and the trackside both see it."""

    schema_version: Literal[1] = 1
    id: Identifier
    name: str = Field(min_length=1, max_length=128)
    length_m: float = Field(gt=0.0, le=2_000_000.0, allow_inf_nan=False, description="[m]")
    ring: bool = Field(default=False, description="Chainage wraps at length_m")
    etcs_level: Literal[1, 2] = 1
    gradient_permille: tuple[ProfileSection, ...] = Field(description="Gradient [‰]")
    curve_radius_m: tuple[ProfileSection, ...] = Field(default=(), description="Signed [m]")
    speed_limit_mps: tuple[ProfileSection, ...] = Field(description="SSP [m/s]")
    temporary_speed_restrictions: tuple[TemporarySpeedRestriction, ...] = ()
    balise_groups: tuple[BaliseGroup, ...] = ()
    stopping_points: tuple[StoppingPoint, ...] = ()
    stop_markers: tuple[StopMarker, ...] = Field(
        default=(), description="Precision-stop markers, by increasing chainage"
    )
    geodetic: tuple[GeoPoint, ...] = Field(default=(), description="Polyline by chainage")

    @model_validator(mode="after")
    def _check(self) -> Self:
        problems = _line_problems(self)
        if problems:
            raise PydanticCustomError(
                "line_rules",
                "{count} problem(s): {text}",
                {"count": len(problems), "text": "; ".join(problems), "problems": problems},
            )
        return self

    def version(self) -> str:
        """SHA-256 of the canonical JSON: the track-data version both sides compare."""
        canonical = self.model_dump_json(round_trip=True).encode()
        return hashlib.sha256(canonical).hexdigest()


def parse_line(document: Mapping[str, Any] | str | bytes) -> Line:
    """Validate a line document; every problem is listed, with its location, in one error."""
    try:
        if isinstance(document, str | bytes):
            return Line.model_validate_json(document)
        return Line.model_validate(document)
    except ValidationError as exc:
        problems: list[str] = []
        for error in exc.errors():
            context = error.get("ctx") or {}
            if error["type"] == "line_rules":
                problems.extend(context["problems"])
            else:
                where = ".".join(str(part) for part in error["loc"]) or "line"
                problems.append(f"{where}: {error['msg']}")
        raise LineValidationError(_document_id(document), problems) from exc


def _document_id(document: Mapping[str, Any] | str | bytes) -> str:
    """The ``id`` a rejected document claims, for the error message; ``?`` if none."""
    if isinstance(document, str | bytes):
        try:
            document = json.loads(document)
        except ValueError:
            return "?"
    return str(document.get("id", "?")) if isinstance(document, Mapping) else "?"


def line_json_schema() -> str:
    """The JSON Schema of a line document: pretty-printed, keys sorted, with a final newline.

    ``trackdb/line.schema.json`` holds this text; regenerate it with
    ``ato trackdb schema > trackdb/line.schema.json`` after changing the models.
    """
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema"} | Line.model_json_schema()
    return json.dumps(schema, indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def _line_problems(line: Line) -> list[str]:
    length = line.length_m
    problems = _check_cover("gradient_permille", line.gradient_permille, length)
    problems += _check_cover("speed_limit_mps", line.speed_limit_mps, length)
    problems += _check_ranges("curve_radius_m", line.curve_radius_m, length)
    for index, section in enumerate(line.speed_limit_mps):
        if section.value <= 0:
            problems.append(f"speed_limit_mps[{index}]: non-positive speed {section.value}")
    for index, section in enumerate(line.curve_radius_m):
        if abs(section.value) < 50.0:
            problems.append(f"curve_radius_m[{index}]: radius {section.value} m below 50 m")
    for index, tsr in enumerate(line.temporary_speed_restrictions):
        where = f"temporary_speed_restrictions[{index}] {tsr.id}"
        if tsr.end_m <= tsr.start_m:
            problems.append(f"{where}: non-positive length {tsr.start_m}..{tsr.end_m}")
        if tsr.end_m > length:
            problems.append(f"{where}: ends beyond the line ({length})")
    problems += _unique(
        "temporary_speed_restrictions", [t.id for t in line.temporary_speed_restrictions]
    )
    problems += _check_points(line)
    problems += _check_geodetic(line)
    return problems


def _unique(name: str, ids: list[Any]) -> list[str]:
    counts = Counter(ids)
    return [f"{name}: duplicate id {item}" for item, count in counts.items() if count > 1]


def _check_points(line: Line) -> list[str]:
    problems: list[str] = []
    for index, point in enumerate(line.stopping_points):
        if point.position_m >= line.length_m:
            problems.append(f"stopping_points[{index}] {point.id}: beyond the line's end")
    problems += _unique("stopping_points", [p.id for p in line.stopping_points])
    problems += _unique("stop_markers", [m.id for m in line.stop_markers])
    for index, marker in enumerate(line.stop_markers):
        where = f"stop_markers[{index}] {marker.id}"
        if marker.position_m >= line.length_m:
            problems.append(f"{where}: beyond the line's end")
        if index and marker.position_m <= line.stop_markers[index - 1].position_m:
            problems.append(f"{where}: not after the previous marker")
    group_ids = {group.id for group in line.balise_groups}
    problems += _unique("balise_groups", [g.id for g in line.balise_groups])
    for index, group in enumerate(line.balise_groups):
        where = f"balise_groups[{index}] {group.id}"
        if group.position_m >= line.length_m:
            problems.append(f"{where}: beyond the line's end")
        if index and group.position_m <= line.balise_groups[index - 1].position_m:
            problems.append(f"{where}: not after the previous group")
        for packet in group.packets:
            if isinstance(packet, LinkingPacket):
                for link in packet.links:
                    if link.balise_group_id not in group_ids:
                        problems.append(
                            f"{where}: links to unknown balise group {link.balise_group_id}"
                        )
            if isinstance(packet, StaticSpeedProfilePacket | GradientPacket):
                problems += _check_packet_sections(where, packet)
    return problems


def _check_packet_sections(
    where: str, packet: StaticSpeedProfilePacket | GradientPacket
) -> list[str]:
    problems = []
    distances = [section.distance_m for section in packet.sections]
    if distances[0] != 0.0:
        problems.append(f"{where}: {packet.type} does not start at the group")
    if any(b <= a for a, b in zip(distances, distances[1:], strict=False)):
        problems.append(f"{where}: {packet.type} distances not increasing")
    if distances[-1] >= packet.length_m:
        problems.append(f"{where}: {packet.type} section beyond its length")
    if isinstance(packet, StaticSpeedProfilePacket) and any(s.value <= 0 for s in packet.sections):
        problems.append(f"{where}: {packet.type} with a non-positive speed")
    return problems


def _check_geodetic(line: Line) -> list[str]:
    points = line.geodetic
    if not points:
        return []
    problems = []
    if len(points) < 2:
        problems.append("geodetic: needs at least two points")
    if points[0].chainage_m != 0.0:
        problems.append(f"geodetic[0]: chainage {points[0].chainage_m}, not 0")
    if not math.isclose(points[-1].chainage_m, line.length_m, abs_tol=1e-6):
        problems.append(f"geodetic: ends at {points[-1].chainage_m}, not at {line.length_m}")
    for index in range(1, len(points)):
        if points[index].chainage_m <= points[index - 1].chainage_m:
            problems.append(f"geodetic[{index}]: chainage not increasing")
    return problems


def _check_ranges(name: str, sections: tuple[ProfileSection, ...], length_m: float) -> list[str]:
    problems = []
    previous_end = 0.0
    for index, section in enumerate(sections):
        where = f"{name}[{index}]"
        if section.end_m <= section.start_m:
            problems.append(f"{where}: non-positive length {section.start_m}..{section.end_m}")
        if section.start_m < previous_end:
            problems.append(f"{where}: starts at {section.start_m}, before {previous_end}")
        if section.end_m > length_m:
            problems.append(f"{where}: ends at {section.end_m}, beyond the line ({length_m})")
        previous_end = max(previous_end, section.end_m)
    return problems


def _check_cover(name: str, sections: tuple[ProfileSection, ...], length_m: float) -> list[str]:
    problems = _check_ranges(name, sections, length_m)
    if not sections:
        return [*problems, f"{name}: empty"]
    if sections[0].start_m != 0.0:
        problems.append(f"{name}[0]: starts at {sections[0].start_m}, not 0")
    for index in range(1, len(sections)):
        if sections[index].start_m > sections[index - 1].end_m:
            problems.append(f"{name}[{index}]: gap after {sections[index - 1].end_m}")
    if sections[-1].end_m != length_m:
        problems.append(f"{name}: ends at {sections[-1].end_m}, not at the line's end {length_m}")
    return problems
