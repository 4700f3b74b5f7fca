"""LineBuilder: lines described as a walk along the track, for seed lines and test layouts.

The walk is a sequence of straights and curves, each with a line speed and a gradient; stopping
points, balise groups and TSRs are placed by chainage. ``build`` merges the walk into profiles,
derives the balise groups' SSP and gradient packets from the line itself, and integrates heading
and altitude into the geodetic polyline (a local tangent plane at the origin, adequate for lines
of a few hundred kilometres).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Self

from protocol.units import MPS_PER_KMH
from trackdb.schema import (
    BaliseGroup,
    BalisePacket,
    GeoPoint,
    GradientPacket,
    Line,
    Link,
    LinkingPacket,
    MovementAuthorityPacket,
    PacketSection,
    ProfileSection,
    StaticSpeedProfilePacket,
    StopMarker,
    StoppingPoint,
    TemporarySpeedRestriction,
    parse_line,
)

__all__ = ["EARTH_RADIUS_M", "LineBuilder", "enu_to_geodetic", "geodetic_to_enu"]

EARTH_RADIUS_M = 6_371_000.0


def enu_to_geodetic(
    east_m: float, north_m: float, origin_lat_deg: float, origin_lon_deg: float
) -> tuple[float, float]:
    """(lat, lon) [deg] of a local east/north offset [m] from the origin (equirectangular)."""
    lat = origin_lat_deg + math.degrees(north_m / EARTH_RADIUS_M)
    lon = origin_lon_deg + math.degrees(
        east_m / (EARTH_RADIUS_M * math.cos(math.radians(origin_lat_deg)))
    )
    return lat, lon


def geodetic_to_enu(
    lat_deg: float, lon_deg: float, origin_lat_deg: float, origin_lon_deg: float
) -> tuple[float, float]:
    """Inverse of :func:`enu_to_geodetic`: (east, north) [m]."""
    north = math.radians(lat_deg - origin_lat_deg) * EARTH_RADIUS_M
    east = (
        math.radians(lon_deg - origin_lon_deg)
        * EARTH_RADIUS_M
        * math.cos(math.radians(origin_lat_deg))
    )
    return east, north


@dataclass
class _Stretch:
    length_m: float
    radius_m: float | None
    speed_mps: float
    gradient_permille: float


@dataclass
class _Group:
    id: int
    position_m: float
    authority_m: float | None
    profile_m: float
    link_next: bool
    extra: tuple[BalisePacket, ...]


@dataclass
class LineBuilder:
    """Build a :class:`Line` by walking it. All lengths in metres, speeds in km/h."""

    id: str
    name: str
    ring: bool = False
    etcs_level: int = 1
    origin_lat_deg: float = 44.4949
    origin_lon_deg: float = 11.3426
    origin_alt_m: float = 50.0
    heading_deg: float = 0.0
    """Initial heading, counterclockwise from east [deg]."""
    _stretches: list[_Stretch] = field(default_factory=list)
    _stops: list[StoppingPoint] = field(default_factory=list)
    _markers: list[StopMarker] = field(default_factory=list)
    _groups: list[_Group] = field(default_factory=list)
    _tsrs: list[TemporarySpeedRestriction] = field(default_factory=list)

    @property
    def length_m(self) -> float:
        return sum(stretch.length_m for stretch in self._stretches)

    def straight(
        self, length_m: float, *, speed_kmh: float, gradient_permille: float = 0.0
    ) -> Self:
        self._stretches.append(_Stretch(length_m, None, speed_kmh * MPS_PER_KMH, gradient_permille))
        return self

    def curve(
        self,
        length_m: float,
        radius_m: float,
        *,
        speed_kmh: float,
        gradient_permille: float = 0.0,
    ) -> Self:
        """A curve of signed radius: positive turns left."""
        self._stretches.append(
            _Stretch(length_m, radius_m, speed_kmh * MPS_PER_KMH, gradient_permille)
        )
        return self

    def stopping_point(
        self,
        id: str,
        name: str,
        position_m: float,
        *,
        tolerance_m: float = 0.5,
        platform_length_m: float = 100.0,
    ) -> Self:
        self._stops.append(
            StoppingPoint(
                id=id,
                name=name,
                position_m=position_m,
                stopping_tolerance_m=tolerance_m,
                platform_length_m=platform_length_m,
            )
        )
        return self

    def stop_marker(self, id: str, position_m: float) -> Self:
        """A precision-stop marker at ``position_m`` [m] (markers go in increasing chainage)."""
        self._markers.append(StopMarker(id=id, position_m=position_m))
        return self

    def balise_group(
        self,
        id: int,
        position_m: float,
        *,
        authority_m: float | None = None,
        profile_m: float = 0.0,
        link_next: bool = True,
        packets: tuple[BalisePacket, ...] = (),
    ) -> Self:
        """A group; with ``authority_m`` it gives an MA that far, with SSP and gradient packets
        over ``profile_m`` (the MA's length by default), read from the line being built."""
        profile = profile_m or (authority_m or 0.0)
        self._groups.append(_Group(id, position_m, authority_m, profile, link_next, packets))
        return self

    def temporary_speed_restriction(
        self, id: str, start_m: float, end_m: float, *, speed_kmh: float
    ) -> Self:
        self._tsrs.append(
            TemporarySpeedRestriction(
                id=id, start_m=start_m, end_m=end_m, speed_mps=speed_kmh * MPS_PER_KMH
            )
        )
        return self

    def build(self, *, geodetic_step_m: float = 10.0) -> Line:
        """The line; invalid walks raise :class:`~trackdb.schema.LineValidationError`."""
        gradients, radii, speeds = self._profiles()
        line_document = {
            "id": self.id,
            "name": self.name,
            "length_m": self.length_m,
            "ring": self.ring,
            "etcs_level": self.etcs_level,
            "gradient_permille": [s.model_dump() for s in gradients],
            "curve_radius_m": [s.model_dump() for s in radii],
            "speed_limit_mps": [s.model_dump() for s in speeds],
            "temporary_speed_restrictions": [t.model_dump() for t in self._tsrs],
            "balise_groups": [g.model_dump() for g in self._balise_groups(gradients, speeds)],
            "stopping_points": [p.model_dump() for p in self._stops],
            "stop_markers": [
                m.model_dump() for m in sorted(self._markers, key=lambda m: m.position_m)
            ],
            "geodetic": [p.model_dump() for p in self._geodetic(geodetic_step_m)],
        }
        return parse_line(line_document)

    def _profiles(
        self,
    ) -> tuple[list[ProfileSection], list[ProfileSection], list[ProfileSection]]:
        gradients: list[ProfileSection] = []
        radii: list[ProfileSection] = []
        speeds: list[ProfileSection] = []
        start = 0.0
        for stretch in self._stretches:
            end = start + stretch.length_m
            _append_merged(gradients, start, end, stretch.gradient_permille)
            _append_merged(speeds, start, end, stretch.speed_mps)
            if stretch.radius_m is not None:
                _append_merged(radii, start, end, stretch.radius_m)
            start = end
        return gradients, radii, speeds

    def _balise_groups(
        self, gradients: list[ProfileSection], speeds: list[ProfileSection]
    ) -> list[BaliseGroup]:
        ordered = sorted(self._groups, key=lambda group: group.position_m)
        groups = []
        for index, group in enumerate(ordered):
            packets: list[BalisePacket] = list(group.extra)
            if group.authority_m is not None:
                packets.append(MovementAuthorityPacket(end_of_authority_m=group.authority_m))
            if group.profile_m > 0:
                packets.append(
                    StaticSpeedProfilePacket(
                        sections=self._packet_sections(speeds, group.position_m, group.profile_m),
                        length_m=group.profile_m,
                    )
                )
                packets.append(
                    GradientPacket(
                        sections=self._packet_sections(
                            gradients, group.position_m, group.profile_m
                        ),
                        length_m=group.profile_m,
                    )
                )
            following = ordered[(index + 1) % len(ordered)] if ordered else None
            if (
                group.link_next
                and following is not None
                and (self.ring or index + 1 < len(ordered))
            ):
                distance = (following.position_m - group.position_m) % self.length_m
                if distance > 0:
                    packets.append(
                        LinkingPacket(
                            links=(Link(distance_m=distance, balise_group_id=following.id),)
                        )
                    )
            groups.append(
                BaliseGroup(id=group.id, position_m=group.position_m, packets=tuple(packets))
            )
        return groups

    def _packet_sections(
        self, profile: list[ProfileSection], position_m: float, length_m: float
    ) -> tuple[PacketSection, ...]:
        """The profile seen from a group over ``length_m`` ahead, wrapping on a ring."""
        sections: list[PacketSection] = []
        travelled = 0.0
        while travelled < length_m:
            chainage = position_m + travelled
            if self.ring:
                chainage %= self.length_m
            elif chainage >= self.length_m:
                break
            section = next(s for s in profile if s.start_m <= chainage < s.end_m)
            if not sections or sections[-1].value != section.value:
                sections.append(PacketSection(distance_m=travelled, value=section.value))
            travelled += section.end_m - chainage
        return tuple(sections)

    def _geodetic(self, step_m: float) -> list[GeoPoint]:
        east = north = 0.0
        altitude = self.origin_alt_m
        heading = math.radians(self.heading_deg)
        chainage = 0.0
        points = [self._geo_point(0.0, east, north, altitude)]
        for stretch in self._stretches:
            curvature = 0.0 if stretch.radius_m is None else 1.0 / stretch.radius_m
            steps = max(1, math.ceil(stretch.length_m / step_m))
            ds = stretch.length_m / steps
            for _ in range(steps):
                if curvature == 0.0:
                    east += ds * math.cos(heading)
                    north += ds * math.sin(heading)
                else:  # exact arc
                    new_heading = heading + curvature * ds
                    east += (math.sin(new_heading) - math.sin(heading)) / curvature
                    north -= (math.cos(new_heading) - math.cos(heading)) / curvature
                    heading = new_heading
                altitude += stretch.gradient_permille / 1000.0 * ds
                chainage += ds
                points.append(self._geo_point(chainage, east, north, altitude))
        last = points[-1]
        points[-1] = last.model_copy(update={"chainage_m": self.length_m})
        return points

    def _geo_point(self, chainage: float, east: float, north: float, altitude: float) -> GeoPoint:
        lat, lon = enu_to_geodetic(east, north, self.origin_lat_deg, self.origin_lon_deg)
        return GeoPoint(
            chainage_m=chainage, latitude_deg=lat, longitude_deg=lon, altitude_m=altitude
        )


def _append_merged(sections: list[ProfileSection], start: float, end: float, value: float) -> None:
    if sections and sections[-1].value == value and sections[-1].end_m == start:
        sections[-1] = sections[-1].model_copy(update={"end_m": end})
    else:
        sections.append(ProfileSection(start_m=start, end_m=end, value=value))
