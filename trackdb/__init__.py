"""Track data: the line schema, the builder and seed lines, and TrackMap, the onboard view.

Depends on ``protocol`` only. Chainage is in metres from the line's origin; on a ring line it
wraps at the line's length. Abbreviations: SSP (static speed profile), TSR (temporary speed
restriction), MRSP (most restrictive speed profile), MA (movement authority), EoA (end of
authority).
"""

from trackdb.builder import LineBuilder
from trackdb.schema import (
    BaliseGroup,
    GeoPoint,
    Line,
    LineValidationError,
    ProfileSection,
    StoppingPoint,
    TemporarySpeedRestriction,
    parse_line,
)
from trackdb.seed_lines import SEED_LINES, load_seed_line
from trackdb.track_map import TrackMap

__all__ = [
    "SEED_LINES",
    "BaliseGroup",
    "GeoPoint",
    "Line",
    "LineBuilder",
    "LineValidationError",
    "ProfileSection",
    "StoppingPoint",
    "TemporarySpeedRestriction",
    "TrackMap",
    "load_seed_line",
    "parse_line",
]
