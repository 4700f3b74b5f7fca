"""Track data: the line schema, the shipped seed lines and TrackMap, the onboard read-only view.

Depends on ``protocol`` only. Chainage is in metres from the line's origin; on a ring line it
wraps at the line's length. Abbreviations: SSP (static speed profile), MRSP (most restrictive
speed profile).
"""

from trackdb.schema import (
    Line,
    LineValidationError,
    ProfileSection,
    StoppingPoint,
    parse_line,
)
from trackdb.seed_lines import SEED_LINES, load_seed_line
from trackdb.track_map import TrackMap

__all__ = [
    "SEED_LINES",
    "Line",
    "LineValidationError",
    "ProfileSection",
    "StoppingPoint",
    "TrackMap",
    "load_seed_line",
    "parse_line",
]
