"""ATO-OB: the onboard process of one vehicle.

Runs every component on the multi-rate executive of :mod:`onboard.runtime`; talks to ATO-TS only
through ``protocol`` messages over Zenoh. Never imports ``trackside``.
Abbreviations: ADF (autonomous driving function), SC (its supervisory controller), RD / AD
(remote / autonomous driving).
"""

from onboard._exceptions import (
    AdfError,
    OnboardError,
    TrackDataCorruptError,
    TrackDataError,
    TrackDataUnavailableError,
)

__all__ = [
    "AdfError",
    "OnboardError",
    "TrackDataCorruptError",
    "TrackDataError",
    "TrackDataUnavailableError",
]
