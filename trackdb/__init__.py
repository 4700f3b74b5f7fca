"""Track data: the line schema, the builder and seed lines, and TrackMap, the onboard view.

Depends on ``protocol`` only. Chainage is in metres from the line's origin; on a ring line it
wraps at the line's length. Abbreviations: SSP (static speed profile), TSR (temporary speed
restriction), MRSP (most restrictive speed profile), MA (movement authority), EoA (end of
authority).

Storage (SQLAlchemy tables, import and export of versioned lines) is in :mod:`trackdb.storage`,
imported on demand so that the onboard side does not load a database layer. The errors are listed
in one place, :mod:`trackdb._exceptions`, and re-exported here.
"""

from trackdb._exceptions import (
    LineConflictError,
    LineNotFoundError,
    LineValidationError,
    NoGeodeticPolylineError,
    RailJsonError,
    TrackDataError,
)
from trackdb._geometry import GeodeticPolyline, GpsProjection
from trackdb.builder import LineBuilder
from trackdb.schema import (
    BaliseGroup,
    GeoPoint,
    Line,
    ProfileSection,
    StopMarker,
    StoppingPoint,
    TemporarySpeedRestriction,
    line_json_schema,
    parse_line,
)
from trackdb.seed_lines import SEED_LINES, load_seed_line
from trackdb.track_map import SpeedSection, TrackMap

__all__ = [
    "SEED_LINES",
    "BaliseGroup",
    "GeoPoint",
    "GeodeticPolyline",
    "GpsProjection",
    "Line",
    "LineBuilder",
    "LineConflictError",
    "LineNotFoundError",
    "LineValidationError",
    "NoGeodeticPolylineError",
    "ProfileSection",
    "RailJsonError",
    "SpeedSection",
    "StopMarker",
    "StoppingPoint",
    "TemporarySpeedRestriction",
    "TrackDataError",
    "TrackMap",
    "line_json_schema",
    "load_seed_line",
    "parse_line",
]
