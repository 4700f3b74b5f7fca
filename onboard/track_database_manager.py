"""The onboard Track Database Manager of seed 000.

Holds the vehicle's TrackMap, compares its track-data version with the trackside's, reviews the
journey profiles the trackside sends (refusing one when the versions differ or its timing points
are not on the line) and localises chainages on the line.
"""

from __future__ import annotations

from dataclasses import dataclass

from protocol import messages as m
from trackdb import TrackMap

__all__ = ["JourneyReview", "TrackDatabaseManager"]

_REFUSED_STATUSES = (m.JourneyProfileStatus.INVALID, m.JourneyProfileStatus.UNAVAILABLE)


@dataclass(frozen=True)
class JourneyReview:
    accepted: bool
    reason: str | None


class TrackDatabaseManager:
    """Track data on board: versions, journey review, localisation."""

    def __init__(self, track_map: TrackMap) -> None:
        self.track_map = track_map
        self.trackside_version: str | None = None
        self.journey: m.JourneyProfile | None = None

    def use_line(self, track_map: TrackMap) -> None:
        """New track data of the same line: a journey accepted on the old ones is dropped."""
        self.track_map = track_map
        self.journey = None

    @property
    def onboard_version(self) -> str:
        return self.track_map.version

    @property
    def line_id(self) -> str:
        return self.track_map.line.id

    def record_trackside_version(self, reply: m.LineVersionReply) -> None:
        """Take the trackside's answer about this line's version."""
        if reply.line_id == self.line_id:
            self.trackside_version = reply.version

    @property
    def versions_match(self) -> bool:
        return self.trackside_version == self.onboard_version

    def review(self, profile: m.JourneyProfile) -> JourneyReview:
        """Accept a journey profile, or refuse it with the first reason found."""
        reason = self._refusal(profile)
        if reason is None:
            self.journey = profile
        return JourneyReview(accepted=reason is None, reason=reason)

    def _refusal(self, profile: m.JourneyProfile) -> str | None:
        if profile.status in _REFUSED_STATUSES:
            return f"journey profile status is {profile.status.value}"
        if profile.line_id != self.line_id:
            return f"journey is for line {profile.line_id}, the vehicle is on {self.line_id}"
        if self.trackside_version is None:
            return "trackside track-data version not known yet"
        if not self.versions_match:
            return "onboard track data differ from the trackside's"
        if profile.track_data_version != self.onboard_version:
            return "journey planned on other track data"
        for point in profile.timing_points:
            if point.position_m >= self.track_map.length_m:
                return f"timing point {point.id} is beyond the line's end"
        return None

    def localise(self, chainage_m: float) -> float:
        """The chainage on the line (wrapped on a ring, clamped on an open line)."""
        return self.track_map.normalise(chainage_m)
