"""The line schema: profiles along chainage, stopping points, and the line's version hash.

A line is a set of piecewise-constant profiles over ``[0, length_m)``: gradient [‰, positive
uphill in the direction of increasing chainage], curve radius [m, absent where straight] and the
static speed profile (SSP) [m/s]. The gradient and SSP profiles must cover the whole line without
gaps or overlaps; curves may leave straight track between them.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Annotated, Any, Self

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from pydantic_core import PydanticCustomError

__all__ = [
    "SCHEMA_VERSION",
    "Line",
    "LineValidationError",
    "ProfileSection",
    "StoppingPoint",
    "parse_line",
]

SCHEMA_VERSION = 1

Identifier = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[a-z0-9][a-z0-9_-]*$")]


class LineValidationError(ValueError):
    """A line that breaks the schema's rules; ``problems`` lists each one with its location."""

    def __init__(self, line_id: str, problems: list[str]) -> None:
        super().__init__(f"line {line_id!r}: " + "; ".join(problems))
        self.problems = problems


class ProfileSection(BaseModel):
    """A constant value over ``[start_m, end_m)``."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    start_m: float = Field(ge=0.0, allow_inf_nan=False, description="Section start [m]")
    end_m: float = Field(gt=0.0, allow_inf_nan=False, description="Section end [m]")
    value: float = Field(allow_inf_nan=False, description="Value, in the profile's unit")


class StoppingPoint(BaseModel):
    """A place where journeys may stop."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: Identifier
    name: str = Field(min_length=1, max_length=128)
    position_m: float = Field(ge=0.0, allow_inf_nan=False, description="Stopping chainage [m]")


class Line(BaseModel):
    """A railway line as the onboard and the trackside both see it."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    schema_version: int = SCHEMA_VERSION
    id: Identifier
    name: str = Field(min_length=1, max_length=128)
    length_m: float = Field(gt=0.0, allow_inf_nan=False, description="Line length [m]")
    ring: bool = Field(default=False, description="Chainage wraps at length_m")
    gradient_permille: tuple[ProfileSection, ...] = Field(description="Gradient [‰]")
    curve_radius_m: tuple[ProfileSection, ...] = Field(default=(), description="Radius [m]")
    speed_limit_mps: tuple[ProfileSection, ...] = Field(description="SSP [m/s]")
    stopping_points: tuple[StoppingPoint, ...] = ()

    @model_validator(mode="after")
    def _check(self) -> Self:
        problems: list[str] = []
        problems += _check_cover("gradient_permille", self.gradient_permille, self.length_m)
        problems += _check_cover("speed_limit_mps", self.speed_limit_mps, self.length_m)
        problems += _check_ranges("curve_radius_m", self.curve_radius_m, self.length_m)
        for index, section in enumerate(self.speed_limit_mps):
            if section.value <= 0:
                problems.append(f"speed_limit_mps[{index}]: non-positive speed {section.value}")
        for index, section in enumerate(self.curve_radius_m):
            if section.value <= 0:
                problems.append(f"curve_radius_m[{index}]: non-positive radius {section.value}")
        for index, point in enumerate(self.stopping_points):
            if point.position_m >= self.length_m:
                problems.append(f"stopping_points[{index}]: {point.id} beyond the line's end")
        if problems:
            raise PydanticCustomError(
                "line_rules", "{count} problem(s): {text}",
                {"count": len(problems), "text": "; ".join(problems), "problems": problems},
            )  # fmt: skip
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
        line_id = document.get("id", "?") if isinstance(document, Mapping) else "?"
        raise LineValidationError(str(line_id), problems) from exc


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
