"""The MA the onboard holds and the track description that bounds it, for :class:`EtcsOnboard`.

:class:`AuthorityKeeper` keeps the MA in force (:class:`AuthorityInForce`, in track locations)
and the reach of the SSP and gradient received (:class:`TrackDescription`, packets 27 and 21),
and answers what the modes and the supervision ask of them: the EoA and the SvL held at the end
of the track description (SUBSET-026 §3.7), whether the track description reaches back to a
location, whether the front end is in the MA's on-sight area. MAs come from balise groups
(Level 1, :mod:`onboard.etcs.balise_intake`) and from the RBC (Level 2,
:meth:`EtcsOnboard.receive_movement_authority`); a trip or isolation forgets both.
"""

from __future__ import annotations

from onboard.etcs._exceptions import EtcsInputError
from onboard.etcs.movement_authority import (
    AuthorityInForce,
    MaChange,
    MovementAuthority,
    TrackDescription,
)
from onboard.etcs.odometry import ConfidenceInterval

__all__ = ["AuthorityKeeper"]


class AuthorityKeeper:
    """The MA in force and the track description, in track locations [m]."""

    def __init__(self) -> None:
        self.in_force: AuthorityInForce | None = None
        self.track_description = TrackDescription()

    def accept(
        self, authority: MovementAuthority, now_s: float, *, reference_location_m: float
    ) -> MaChange:
        """``authority`` in force from now, its reference at ``reference_location_m`` [m]."""
        new = AuthorityInForce.resolve(
            authority, reference_location_m=reference_location_m, now_s=now_s
        )
        old = self.in_force
        self.in_force = new
        if old is None:
            return MaChange.NEW
        if new.end_of_authority_m > old.end_of_authority_m:
            return MaChange.EXTENDED
        if new.end_of_authority_m < old.end_of_authority_m:
            return MaChange.SHORTENED
        return MaChange.UNCHANGED

    def accept_with_track_description(
        self,
        authority: MovementAuthority,
        now_s: float,
        *,
        reference_location_m: float,
        track_description_m: float | None,
    ) -> MaChange:
        """A radio MA with the SSP and gradient it comes with, reaching ``track_description_m``
        [m] from the reference (up to the SvL when None)."""
        change = self.accept(authority, now_s, reference_location_m=reference_location_m)
        if track_description_m is None:
            track_description_m = authority.end_of_authority_m + max(
                authority.danger_point_m, authority.overlap_m
            )
        end_m = reference_location_m + track_description_m
        self.track_description.receive_static_speed_profile(reference_location_m, end_m)
        self.track_description.receive_gradient(reference_location_m, end_m)
        return change

    def locations(self) -> tuple[float, float]:
        """(EoA, SvL) [m], held at the end of the track description (§3.7)."""
        if self.in_force is None:  # pragma: no cover - callers check
            raise EtcsInputError("no movement authority")
        return self.track_description.held_authority_m(self.in_force)

    def update(self, now_s: float, interval: ConfidenceInterval) -> None:
        """Run the MA's timers at ``now_s`` [s] with the train's confidence interval."""
        if self.in_force is not None:
            self.in_force.update(
                now_s,
                min_safe_front_m=interval.min_safe_front_m,
                max_safe_front_m=interval.max_safe_front_m,
            )

    def described_from(self, location_m: float) -> bool:
        """Whether SSP and gradient are both known from ``location_m`` [m] or before it on."""
        span = self.track_description.span_m
        return span is not None and span[0] <= location_m

    def in_on_sight_area(self, front_m: float, train_length_m: float) -> bool:
        """Whether the train, its front end at ``front_m`` [m], is in the MA's on-sight area."""
        authority = self.in_force
        if authority is None or authority.authority.on_sight is None:
            return False
        area = authority.authority.on_sight
        start_m = authority.reference_location_m + area.start_m
        end_m = authority.reference_location_m + area.end_m
        # The area holds from the front end's entry until the rear end has left it.
        return start_m <= front_m < end_m + train_length_m

    def clear(self) -> None:
        """Forget the MA and the track description (trip, isolation)."""
        self.in_force = None
        self.track_description.clear()
