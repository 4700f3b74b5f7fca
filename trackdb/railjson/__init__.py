"""RailJSON import: one of our lines from an OSRD RailJSON infrastructure document (3.x).

:func:`line_from_railjson` reads the document (:mod:`~trackdb.railjson.models`), builds the
track-section graph and searches the path from one operational point to another through the
ones given with ``via`` (:mod:`~trackdb.railjson.graph`), extends it by a run-in before the
origin and an overrun after the destination, and maps what lies along it onto the line:
profiles (:mod:`~trackdb.railjson.profiles`), stopping points, precision-stop markers, balise
groups and the geodetic polyline (:mod:`~trackdb.railjson.places`). The line is ETCS Level 2
(the RBC emulator gives the movement authorities). docs/trackdb.md ("RailJSON import") lists
every rule.

Every problem is a :class:`RailJsonError` naming the place in the document as a JSON path
(``$.track_sections[12].length``) and the reason. No database here: storing is
:func:`trackdb.storage.import_line`'s.
"""

from __future__ import annotations

from trackdb._exceptions import RailJsonError
from trackdb.railjson.importer import (
    DEFAULT_BALISE_SPACING_M,
    DEFAULT_LINE_SPEED_KMH,
    DEFAULT_MARGIN_M,
    MAX_DOCUMENT_BYTES,
    line_from_railjson,
    read_infra,
)
from trackdb.railjson.places import stopping_point_id

__all__ = [
    "DEFAULT_BALISE_SPACING_M",
    "DEFAULT_LINE_SPEED_KMH",
    "DEFAULT_MARGIN_M",
    "MAX_DOCUMENT_BYTES",
    "RailJsonError",
    "line_from_railjson",
    "read_infra",
    "stopping_point_id",
]
