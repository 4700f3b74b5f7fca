"""The rules an RBC movement authority (MA) must follow, and how one is built from another.

Pure functions used by :class:`trackside.rbc.RbcEmulator`: where an MA may lie on a line
(:func:`check_on_line`), where a reported position lies relative to an MA on a ring
(:func:`unwrapped`), what an extension or a shortening makes of an MA (:func:`extended`,
:func:`shortened`, which cuts the sections with :func:`cut_sections`), and pydantic's
validation errors turned into a refusal that lists them (:func:`built`,
:func:`speed_restriction`). :mod:`trackside.rbc_checks` applies them with the lines and
positions the trackside knows.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

from pydantic import ValidationError

from protocol import messages as m
from trackside.errors import MovementAuthorityRefusedError

__all__ = [
    "LineInfo",
    "LineInfoLookup",
    "as_end",
    "built",
    "check_on_line",
    "check_vehicle_id",
    "cut_sections",
    "extended",
    "extent_from",
    "rebuilt",
    "shortened",
    "speed_restriction",
    "unwrapped",
]

T = TypeVar("T")
EndModel = TypeVar("EndModel", bound=m.MovementAuthorityEnd)

_VEHICLE_ID = re.compile(r"^[A-Za-z0-9_-]{1,32}$")


@dataclass(frozen=True, kw_only=True)
class LineInfo:
    """What the RBC knows of a line: its current track-data version and its extent."""

    version: str
    length_m: float
    ring: bool


LineInfoLookup = Callable[[str], LineInfo | None]
"""A line's :class:`LineInfo`, ``None`` when the trackside does not hold the line."""


def check_vehicle_id(vehicle_id: str) -> None:
    if not _VEHICLE_ID.fullmatch(vehicle_id):
        raise MovementAuthorityRefusedError(
            f"bad vehicle id {vehicle_id!r}: 1 to 32 letters, digits, '_' or '-'"
        )


def built(build: Callable[[], T]) -> T:
    """``build()``, its validation errors turned into a refusal that lists them."""
    try:
        return build()
    except ValidationError as exc:
        problems = "; ".join(
            str(error["msg"]).removeprefix("Value error, ") for error in exc.errors()
        )
        raise MovementAuthorityRefusedError(problems) from exc


def speed_restriction(
    vehicle_id: str,
    *,
    restriction_id: str,
    line_id: str,
    start_m: float,
    end_m: float,
    speed_mps: float | None,
) -> m.SpeedRestrictionMessage:
    """A TSR for the vehicle (its revocation when ``speed_mps`` is None) [m, m/s]; a refusal
    when the values do not make one."""
    try:
        return m.SpeedRestrictionMessage(
            vehicle_id=vehicle_id,
            restriction_id=restriction_id,
            line_id=line_id,
            start_m=start_m,
            end_m=end_m,
            speed_mps=speed_mps,
        )
    except ValidationError as exc:
        raise MovementAuthorityRefusedError("not a speed restriction", problems=[str(exc)]) from exc


def rebuilt(model: type[EndModel], source: m.MovementAuthorityEnd) -> EndModel:
    """``source``'s fields that ``model`` has, as a ``model`` (a base of ``source``'s class)."""
    return model.model_validate({name: getattr(source, name) for name in model.model_fields})


def as_end(end: m.MovementAuthorityEnd | float) -> m.MovementAuthorityEnd:
    if isinstance(end, m.MovementAuthorityEnd):
        return rebuilt(m.MovementAuthorityEnd, end)
    return built(lambda: m.MovementAuthorityEnd(end_of_authority_m=end))


def extent_from(
    start_m: float,
    end: m.MovementAuthorityEnd,
    sections: tuple[m.MovementAuthoritySection, ...],
    track_description_m: float | None,
) -> m.MovementAuthorityExtent:
    return m.MovementAuthorityExtent(
        **end.model_dump(),
        start_m=start_m,
        sections=sections,
        track_description_m=track_description_m,
    )


def cut_sections(
    sections: tuple[m.MovementAuthoritySection, ...], length_m: float
) -> tuple[m.MovementAuthoritySection, ...]:
    """The sections up to ``length_m`` [m] from the start, the last one cut there."""
    kept: list[m.MovementAuthoritySection] = []
    start_m = 0.0
    for section in sections:
        if start_m >= length_m:
            break
        end_m = start_m + section.length_m
        if end_m >= length_m:
            cut_m = length_m - start_m
            section = section.model_copy(
                update={"length_m": cut_m, "timer_stop_m": min(section.timer_stop_m, cut_m)}
            )
        kept.append(section)
        start_m = end_m
    return tuple(kept)


def extended(
    old: m.MovementAuthorityExtent, end: m.MovementAuthorityEnd
) -> m.MovementAuthorityExtent:
    """The MA ``old`` with its EoA moved forward to ``end`` (and the new end's attributes).

    The start stays; sections, if the MA has them, gain one up to the new EoA, without a timer.
    """
    if not end.end_of_authority_m > old.end_of_authority_m:
        raise MovementAuthorityRefusedError(
            f"an extension must move the EoA forward: {end.end_of_authority_m:g} m "
            f"is not beyond the current EoA at {old.end_of_authority_m:g} m"
        )
    sections = old.sections
    if sections:
        added_m = end.end_of_authority_m - old.end_of_authority_m
        sections = (*sections, m.MovementAuthoritySection(length_m=added_m))
    return built(lambda: extent_from(old.start_m, end, sections, None))


def shortened(
    old: m.MovementAuthorityExtent, end: m.MovementAuthorityEnd
) -> m.MovementAuthorityExtent:
    """The MA ``old`` with its EoA moved back to ``end`` (and the new end's attributes).

    The start and the track description stay; sections beyond the new EoA are dropped and the
    one it falls in is cut there.
    """
    eoa_m = end.end_of_authority_m
    if not eoa_m < old.end_of_authority_m:
        raise MovementAuthorityRefusedError(
            f"a shortening must move the EoA back: {eoa_m:g} m is not before the current "
            f"EoA at {old.end_of_authority_m:g} m"
        )
    if not eoa_m > old.start_m:
        raise MovementAuthorityRefusedError(
            f"a shortened EoA must stay beyond the MA's start at {old.start_m:g} m, "
            f"not {eoa_m:g} m; revoke the MA instead"
        )
    sections = cut_sections(old.sections, eoa_m - old.start_m)
    return built(lambda: extent_from(old.start_m, end, sections, old.track_description_m))


def check_on_line(extent: m.MovementAuthorityExtent, line_id: str, info: LineInfo | None) -> None:
    if info is None:
        return
    svl_m = extent.supervised_location_m
    if info.ring:
        if not 0.0 <= extent.start_m < info.length_m:
            raise MovementAuthorityRefusedError(
                f"the start at {extent.start_m:g} m is not a chainage of ring line {line_id} "
                f"(0 to {info.length_m:g} m)"
            )
        if svl_m - extent.start_m >= info.length_m:
            raise MovementAuthorityRefusedError(
                f"an MA on ring line {line_id} must reach less than one lap "
                f"({info.length_m:g} m) from its start to its SvL"
            )
        return
    if extent.start_m < 0.0 or svl_m > info.length_m:
        raise MovementAuthorityRefusedError(
            f"the MA from {extent.start_m:g} m to its SvL at {svl_m:g} m leaves line {line_id} "
            f"(0 to {info.length_m:g} m)"
        )


def unwrapped(position_m: float, start_m: float, end_m: float, info: LineInfo | None) -> float:
    """On a ring, the location of ``position_m`` nearest the stretch ``[start_m, end_m]`` [m]."""
    if info is None or not info.ring:
        return position_m
    ahead_m = start_m + (position_m - start_m) % info.length_m
    behind_m = ahead_m - info.length_m

    def distance_m(location_m: float) -> float:
        return max(start_m - location_m, 0.0, location_m - end_m)

    return min((ahead_m, behind_m), key=distance_m)
