"""The RBC's messages on board: movement authorities for ETCS, speed restrictions for the map.

The RBC emulator's wire messages (``protocol.messages``) become the ETCS onboard's
:class:`~onboard.etcs.MovementAuthority` and the TrackMap's
:class:`~trackdb.TemporarySpeedRestriction`, which ETCS and the ADF share.
"""

from __future__ import annotations

from onboard.etcs import EtcsOnboard, MaSection, MovementAuthority
from protocol import messages as m
from protocol.units import MPS_PER_KMH
from trackdb import TemporarySpeedRestriction, TrackMap

__all__ = ["authority_from_extent", "receive_movement_authority", "receive_speed_restriction"]


def authority_from_extent(extent: m.MovementAuthorityExtent) -> MovementAuthority:
    """The ETCS onboard's MA from the RBC's wire extent: distances from its start (packet 15)."""
    return MovementAuthority(
        reference_m=extent.start_m,
        end_of_authority_m=extent.length_m,
        danger_point_m=extent.danger_point_m,
        overlap_m=extent.overlap_m,
        overlap_timer_s=extent.overlap_timer_s,
        overlap_timer_start_m=extent.overlap_timer_start_m,
        release_speed_mps=extent.release_speed_mps,
        sections=tuple(
            MaSection(length_m=s.length_m, timer_s=s.timer_s, timer_stop_m=s.timer_stop_m)
            for s in extent.sections
        ),
    )


def receive_movement_authority(
    etcs: EtcsOnboard, message: m.MovementAuthorityMessage, now_s: float
) -> str:
    """Hand an RBC message to ETCS at ``now_s`` [s] (no authority: an emergency stop); what
    happened, for the event log."""
    if message.authority is None:
        etcs.emergency_stop(now_s)
        return "revoked: emergency stop"
    change = etcs.receive_movement_authority(
        authority_from_extent(message.authority),
        now_s,
        track_description_m=message.authority.track_description_m,
    )
    return change.value


def receive_speed_restriction(
    track_map: TrackMap, message: m.SpeedRestrictionMessage
) -> tuple[str, bool]:
    """Put an RBC's TSR in force on the TrackMap, or revoke it: what happened, for the event
    log, and whether the speed limits changed.

    Raises
    ------
    ValueError
        If it is for another line, or its range is not on this line.
    """
    if message.line_id != track_map.line.id:
        raise ValueError(
            f"TSR on line {message.line_id!r}, the vehicle is on {track_map.line.id!r}"
        )
    if message.speed_mps is None:
        if not track_map.revoke_temporary_speed_restriction(message.restriction_id):
            return f"TSR {message.restriction_id} not in force: nothing to revoke", False
        return f"TSR {message.restriction_id} revoked", True
    restriction = TemporarySpeedRestriction(
        id=message.restriction_id,
        start_m=message.start_m,
        end_m=message.end_m,
        speed_mps=message.speed_mps,
    )
    what = (
        f"TSR {message.restriction_id} {message.speed_mps / MPS_PER_KMH:.0f} km/h over "
        f"{message.start_m:.0f}..{message.end_m:.0f} m"
    )
    if restriction in track_map.temporary_speed_restrictions:
        # Sent again (the RBC's answer at a new session): already in force, nothing to plan.
        return f"{what}: already in force", False
    track_map.add_temporary_speed_restriction(restriction)
    return what, True
