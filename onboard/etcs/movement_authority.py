"""Movement authorities: EoA, SvL, release speed, section and overlap timers (SUBSET-026 §3.8).

A :class:`MovementAuthority` is what the track sends: distances [m] counted from a reference
location given as a chainage (the balise group that sent it in Level 1, packet 12; the LRBG for
an RBC's packet 15 in Level 2). Its sections may carry timers.

:class:`AuthorityInForce` is the MA the onboard holds, resolved to track locations (chainage,
unwrapped on a ring). The supervised location (SvL) is, after A.3.4.1.2 d (DOMAIN.md §1.7):

- the end of the overlap if there is one and its timer has not run out, otherwise
- the danger point if there is one, otherwise
- the EoA.

Timers (§3.8.4):

- a section timer starts when the MA is received and stops when the min-safe front end passes
  its stop location; if it runs out first, the MA is shortened to the section's start (EoA and
  SvL there, the sections beyond dropped);
- the overlap timer starts when the max-safe front end passes its start location (D_STARTOL
  before the EoA); when it runs out the overlap is dropped and the SvL falls back to the danger
  point or the EoA.

A new MA replaces the one in force (shortening or extension); :class:`MaChange` says which.

:class:`TrackDescription` keeps how far the SSP (packet 27) and the gradient (packet 21) reach;
the EoA and SvL are held at its end (§3.7), and FS needs it to reach the front end.
The release speed is the MA's when given, otherwise calculated on board from the SvL's EBI
(see :meth:`onboard.etcs.EtcsOnboard.step`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum, StrEnum

from onboard.etcs._exceptions import MovementAuthorityError
from trackdb.schema import MovementAuthorityPacket

__all__ = [
    "AuthorityInForce",
    "EtcsLevel",
    "MaChange",
    "MaSection",
    "MovementAuthority",
    "OnSightArea",
    "TrackDescription",
]


class EtcsLevel(IntEnum):
    """ETCS application levels modelled: 1 (balise MAs) and 2 (radio MAs from the RBC)."""

    LEVEL_1 = 1
    LEVEL_2 = 2


class MaChange(StrEnum):
    """What a received MA did to the one in force."""

    NEW = "new"
    EXTENDED = "extended"
    SHORTENED = "shortened"
    UNCHANGED = "unchanged"
    REJECTED = "rejected"
    """Refused by the mode (TR, IS) or the level (a balise MA in Level 2)."""


def _finite_at_least(value: float, low: float, what: str) -> None:
    if not (math.isfinite(value) and value >= low):
        raise MovementAuthorityError(f"{what} {value} must be finite and ≥ {low}")


@dataclass(frozen=True, kw_only=True)
class MaSection:
    """A section of the MA: its length [m] and an optional timer (Q_SECTIONTIMER)."""

    length_m: float
    timer_s: float | None = None
    """T_SECTIONTIMER [s], counted from the MA's reception."""
    timer_stop_m: float = 0.0
    """D_SECTIONTIMERSTOPLOC [m] from the section's start: passing it stops the timer."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.length_m) and self.length_m > 0.0):
            raise MovementAuthorityError(f"section length {self.length_m} m must be positive")
        if self.timer_s is not None:
            _finite_at_least(self.timer_s, 0.0, "section timer [s]")
        _finite_at_least(self.timer_stop_m, 0.0, "section timer stop location [m]")


@dataclass(frozen=True, kw_only=True)
class OnSightArea:
    """A mode profile for On Sight: from ``start_m`` to ``end_m`` [m] after the reference."""

    start_m: float
    end_m: float
    speed_mps: float | None = None
    """Speed limit [m/s] in the area; None uses V_NVONSIGHT."""

    def __post_init__(self) -> None:
        _finite_at_least(self.start_m, 0.0, "on-sight area start [m]")
        if not (math.isfinite(self.end_m) and self.end_m > self.start_m):
            raise MovementAuthorityError("an on-sight area must end after it starts")
        if self.speed_mps is not None:
            _finite_at_least(self.speed_mps, 0.0, "on-sight speed [m/s]")


@dataclass(frozen=True, kw_only=True)
class MovementAuthority:
    """An MA as sent: distances [m] from the reference, whose chainage is ``reference_m``."""

    reference_m: float
    end_of_authority_m: float
    danger_point_m: float = 0.0
    """EoA to the danger point [m]; 0 for none."""
    overlap_m: float = 0.0
    """EoA to the end of the overlap [m]; 0 for none."""
    overlap_timer_s: float | None = None
    """T_OL [s]; None for no timer."""
    overlap_timer_start_m: float = 0.0
    """D_STARTOL [m]: the overlap timer starts this far before the EoA."""
    release_speed_mps: float | None = None
    """Release speed [m/s]; None: calculated on board."""
    sections: tuple[MaSection, ...] = ()
    """Optional sections; when given, their lengths add up to ``end_of_authority_m``."""
    on_sight: OnSightArea | None = None
    level: EtcsLevel = EtcsLevel.LEVEL_2

    def __post_init__(self) -> None:
        _finite_at_least(self.reference_m, -math.inf, "reference chainage [m]")
        if not (math.isfinite(self.end_of_authority_m) and self.end_of_authority_m > 0.0):
            raise MovementAuthorityError(
                f"EoA distance {self.end_of_authority_m} m must be positive"
            )
        _finite_at_least(self.danger_point_m, 0.0, "danger point distance [m]")
        _finite_at_least(self.overlap_m, 0.0, "overlap distance [m]")
        _finite_at_least(self.overlap_timer_start_m, 0.0, "overlap timer start distance [m]")
        if self.overlap_m and self.overlap_m < self.danger_point_m:
            raise MovementAuthorityError("the overlap must end beyond the danger point")
        if self.overlap_timer_s is not None:
            _finite_at_least(self.overlap_timer_s, 0.0, "overlap timer [s]")
        if self.release_speed_mps is not None:
            _finite_at_least(self.release_speed_mps, 0.0, "release speed [m/s]")
        if self.sections:
            total_m = sum(section.length_m for section in self.sections)
            if not math.isclose(total_m, self.end_of_authority_m, rel_tol=1e-9, abs_tol=1e-6):
                raise MovementAuthorityError(
                    f"sections add up to {total_m} m, not the EoA's {self.end_of_authority_m} m"
                )

    @classmethod
    def from_packet(
        cls, packet: MovementAuthorityPacket, *, reference_m: float
    ) -> MovementAuthority:
        """The Level 1 MA of a balise group's packet 12, the group at chainage ``reference_m``."""
        return cls(
            reference_m=reference_m,
            end_of_authority_m=packet.end_of_authority_m,
            danger_point_m=packet.danger_point_m,
            overlap_m=packet.overlap_m,
            release_speed_mps=packet.release_speed_mps,
            level=EtcsLevel.LEVEL_1,
        )


@dataclass
class _SectionTimer:
    start_m: float
    stop_m: float
    expires_s: float
    running: bool = True


@dataclass
class AuthorityInForce:
    """The MA the onboard holds, resolved to track locations [m], with its timers.

    Build it with :meth:`resolve`; :meth:`update` runs the timers every cycle.
    """

    authority: MovementAuthority
    reference_location_m: float
    end_of_authority_m: float
    danger_point_m: float | None
    overlap_end_m: float | None
    release_speed_mps: float | None
    _section_timers: list[_SectionTimer] = field(default_factory=list)
    _overlap_start_m: float | None = None
    _overlap_expires_s: float | None = None

    @classmethod
    def resolve(
        cls, authority: MovementAuthority, *, reference_location_m: float, now_s: float
    ) -> AuthorityInForce:
        """The MA in force, its reference at ``reference_location_m`` [m], received at now."""
        ma = authority
        eoa_m = reference_location_m + ma.end_of_authority_m
        timers: list[_SectionTimer] = []
        start_m = reference_location_m
        for section in ma.sections:
            if section.timer_s is not None:
                timers.append(
                    _SectionTimer(start_m, start_m + section.timer_stop_m, now_s + section.timer_s)
                )
            start_m += section.length_m
        overlap_start_m = None
        if ma.overlap_m and ma.overlap_timer_s is not None:
            overlap_start_m = eoa_m - ma.overlap_timer_start_m
        return cls(
            authority=ma,
            reference_location_m=reference_location_m,
            end_of_authority_m=eoa_m,
            danger_point_m=eoa_m + ma.danger_point_m if ma.danger_point_m else None,
            overlap_end_m=eoa_m + ma.overlap_m if ma.overlap_m else None,
            release_speed_mps=ma.release_speed_mps,
            _section_timers=timers,
            _overlap_start_m=overlap_start_m,
        )

    @property
    def supervised_location_m(self) -> float:
        """The SvL [m]: end of overlap, else danger point, else EoA."""
        if self.overlap_end_m is not None:
            return self.overlap_end_m
        if self.danger_point_m is not None:
            return self.danger_point_m
        return self.end_of_authority_m

    def shorten_to(self, location_m: float) -> bool:
        """Move the EoA back to ``location_m`` [m] (SvL with it); False if not behind."""
        if location_m >= self.end_of_authority_m:
            return False
        self.end_of_authority_m = location_m
        self.danger_point_m = self.overlap_end_m = None
        self._overlap_start_m = self._overlap_expires_s = None
        self._section_timers = [t for t in self._section_timers if t.start_m < location_m]
        return True

    def update(self, now_s: float, *, min_safe_front_m: float, max_safe_front_m: float) -> bool:
        """Run the timers; True if one ran out and changed the MA."""
        changed = False
        for timer in list(self._section_timers):
            if timer.running and min_safe_front_m >= timer.stop_m:
                timer.running = False
            if timer.running and now_s >= timer.expires_s:
                changed |= self.shorten_to(timer.start_m)
        if self._overlap_start_m is not None and self.overlap_end_m is not None:
            overlap_timer_s = self.authority.overlap_timer_s
            if self._overlap_expires_s is None and max_safe_front_m >= self._overlap_start_m:
                self._overlap_expires_s = now_s + (overlap_timer_s or 0.0)
            if self._overlap_expires_s is not None and now_s >= self._overlap_expires_s:
                self.overlap_end_m = None
                self._overlap_start_m = self._overlap_expires_s = None
                changed = True
        return changed


class TrackDescription:
    """How far the SSP and the gradient received reach, in track locations [m].

    A new profile replaces the known one from its own start on; where it starts inside the
    known one, the coverage runs on from the known start.
    """

    def __init__(self) -> None:
        self.static_speed_profile: tuple[float, float] | None = None
        self.gradient: tuple[float, float] | None = None

    def receive_static_speed_profile(self, start_m: float, end_m: float) -> None:
        """A packet 27 covering ``[start_m, end_m)`` [m]."""
        self.static_speed_profile = _extended(self.static_speed_profile, (start_m, end_m))

    def receive_gradient(self, start_m: float, end_m: float) -> None:
        """A packet 21 covering ``[start_m, end_m)`` [m]."""
        self.gradient = _extended(self.gradient, (start_m, end_m))

    def clear(self) -> None:
        """Forget both (trip, isolation)."""
        self.static_speed_profile = self.gradient = None

    @property
    def span_m(self) -> tuple[float, float] | None:
        """``(start, end)`` [m] where both SSP and gradient are known; None if nowhere."""
        if self.static_speed_profile is None or self.gradient is None:
            return None
        start_m = max(self.static_speed_profile[0], self.gradient[0])
        end_m = min(self.static_speed_profile[1], self.gradient[1])
        return (start_m, end_m) if start_m < end_m else None

    def held_authority_m(self, authority: AuthorityInForce) -> tuple[float, float]:
        """(EoA, SvL) [m] of ``authority``, held at the end of the track description."""
        eoa_m, svl_m = authority.end_of_authority_m, authority.supervised_location_m
        span = self.span_m
        if span is not None and span[1] < eoa_m:
            return span[1], span[1]
        if span is not None:
            svl_m = min(svl_m, span[1])
        return eoa_m, svl_m


def _extended(
    known: tuple[float, float] | None, received: tuple[float, float]
) -> tuple[float, float]:
    if known is not None and known[0] <= received[0] <= known[1]:
        return known[0], received[1]
    return received
