"""A line as GeoJSON (RFC 7946), for map tools: its polyline and its stopping points.

The canonical export stays our own line document; this one is a view of it. One
``FeatureCollection``: a ``LineString`` of the geodetic polyline (longitude, latitude, altitude
[deg, deg, m]) with the line's id, name, length and version, then a ``Point`` per stopping point
with its id, name and chainage [m].
"""

from __future__ import annotations

from typing import Any

from trackdb._exceptions import NoGeodeticPolylineError
from trackdb._geometry import GeodeticPolyline
from trackdb.schema import Line

__all__ = ["line_geojson"]


def line_geojson(line: Line) -> dict[str, Any]:
    """The FeatureCollection; :class:`NoGeodeticPolylineError` for a line without a polyline."""
    if not line.geodetic:
        raise NoGeodeticPolylineError(f"line {line.id!r} has no geodetic polyline")
    polyline = GeodeticPolyline(line.geodetic, length_m=line.length_m, ring=line.ring)
    features: list[dict[str, Any]] = [
        {
            "type": "Feature",
            "geometry": {
                "type": "LineString",
                "coordinates": [
                    [p.longitude_deg, p.latitude_deg, p.altitude_m] for p in line.geodetic
                ],
            },
            "properties": {
                "kind": "line",
                "id": line.id,
                "name": line.name,
                "length_m": line.length_m,
                "ring": line.ring,
                "version": line.version(),
            },
        }
    ]
    for stop in line.stopping_points:
        latitude, longitude, altitude = polyline.at(stop.position_m)
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [longitude, latitude, altitude]},
                "properties": {
                    "kind": "stopping_point",
                    "id": stop.id,
                    "name": stop.name,
                    "chainage_m": stop.position_m,
                },
            }
        )
    return {"type": "FeatureCollection", "features": features}
