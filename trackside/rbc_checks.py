"""What the RBC emulator checks a change against: the lines it holds, the positions reported.

:class:`MovementAuthorityChecks` applies the rules of :mod:`trackside.rbc_rules` with the
lookups :class:`trackside.rbc.RbcEmulator` is given: ``line_info`` (each line's current
track-data version and extent) and ``positions`` (each vehicle's latest status report). Without
a lookup the checks that need it are skipped, as a lockstep test wants. Every refusal is a
:class:`~trackside.errors.MovementAuthorityRefusedError`, raised before anything is sent.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from protocol import messages as m
from trackside.errors import EndOfAuthorityBehindVehicleError, MovementAuthorityRefusedError
from trackside.rbc_rules import LineInfo, LineInfoLookup, unwrapped

__all__ = ["MovementAuthorityChecks", "PositionLookup"]

PositionLookup = Callable[[str], m.StatusReport | None]
"""The vehicle's latest status report, ``None`` when none is known (or the vehicle is gone)."""


class MovementAuthorityChecks:
    """The RBC's checks of MAs and TSRs against the lines and the vehicles' positions.

    Parameters
    ----------
    line_info
        Each line's current version and extent; without it, MAs must name their line version
        and are not checked against the line.
    positions
        Each vehicle's latest status report; without it, EoAs are not checked against positions.
    margin_m
        An EoA must lie more than this far [m] ahead of the reported front end.
    """

    def __init__(
        self,
        *,
        line_info: LineInfoLookup | None = None,
        positions: PositionLookup | None = None,
        margin_m: float = 0.0,
    ) -> None:
        if not (math.isfinite(margin_m) and margin_m >= 0.0):
            raise ValueError(f"margin {margin_m} m must be finite and ≥ 0")
        self._line_info = line_info
        self._positions = positions
        self._margin_m = margin_m

    def info(self, line_id: str) -> LineInfo | None:
        """The line's version and extent; ``None`` if unknown or not looked up."""
        return None if self._line_info is None else self._line_info(line_id)

    def line_version(self, line_id: str, version: str | None) -> tuple[str, LineInfo | None]:
        """The track-data version an MA on the line goes out with, and the line's info.

        ``version`` None takes the line's current one; any other must be the current one.
        """
        info = self.info(line_id)
        if self._line_info is not None and info is None:
            raise MovementAuthorityRefusedError(f"the trackside holds no line {line_id!r}")
        if version is None:
            if info is None:
                raise MovementAuthorityRefusedError(
                    f"the track-data version of line {line_id!r} is not known here: "
                    "give line_version"
                )
            return info.version, info
        if info is not None and version != info.version:
            raise MovementAuthorityRefusedError(
                f"line {line_id!r} is at version {info.version}, not {version}"
            )
        return version, info

    def check_ahead_of_vehicle(
        self,
        vehicle_id: str,
        line_id: str,
        extent: m.MovementAuthorityExtent,
        info: LineInfo | None,
        *,
        reach_m: float | None = None,
    ) -> None:
        """Refuse an EoA at or behind the vehicle's reported front end, plus the margin [m].

        On a ring the position is unwrapped to the location nearest the stretch from the MA's
        start to ``reach_m`` (by default its EoA).
        """
        report = None if self._positions is None else self._positions(vehicle_id)
        if report is None or report.line_id != line_id:
            return
        far_m = extent.end_of_authority_m if reach_m is None else reach_m
        position_m = unwrapped(report.position_m, extent.start_m, far_m, info)
        eoa_m = extent.end_of_authority_m
        if eoa_m <= position_m + self._margin_m:
            margin = f" plus the {self._margin_m:g} m margin" if self._margin_m else ""
            raise EndOfAuthorityBehindVehicleError(
                f"the EoA at {eoa_m:g} m would lie at or behind {vehicle_id}'s front end, last "
                f"reported at {report.position_m:g} m{margin}",
                end_of_authority_m=eoa_m,
                position_m=report.position_m,
            )

    def check_speed_restriction(self, vehicle_id: str, message: m.SpeedRestrictionMessage) -> None:
        """Refuse a TSR for another vehicle, on a line not held, or off its line."""
        if message.vehicle_id != vehicle_id:
            raise MovementAuthorityRefusedError(
                f"TSR for {message.vehicle_id} sent to {vehicle_id}"
            )
        info = self.info(message.line_id)
        if self._line_info is not None and info is None:
            raise MovementAuthorityRefusedError(f"the trackside holds no line {message.line_id!r}")
        if info is not None and message.end_m > info.length_m:
            raise MovementAuthorityRefusedError(
                f"TSR {message.restriction_id!r}: {message.start_m:g}..{message.end_m:g} m is"
                f" not on line {message.line_id!r} (0..{info.length_m:g} m)"
            )
