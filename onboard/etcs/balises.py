"""Reading balise groups (SUBSET-026 §3.4, §7–8; DOMAIN.md §1.7).

A group comes from the balise reader (a :class:`onboard.plant.readings.BaliseDetection`, on
the sensor path) or, on the given-motion path, from the track database between two odometer
positions (:func:`balise_groups_passed`). Passing a group yields a :class:`BaliseGroupReading`:
the group's packets, decoded into what the onboard uses (a Level 1 MA, how far the SSP and
gradient reach, a level transition, the groups linked next), and the :class:`TelegramHeader`
the Vital Control forwards to the ATO-OB (seed 004: the VC decodes the BTM telegram and sends
its header on). The onboard then makes the group its LRBG and relocates the odometry on it.

⚠ trackdb holds no balise count per group: a group reads as one balise (N_PIG 0, N_TOTAL 0).
M_VERSION is 2.0 (32) by default; NID_C is the line's country code, 0 by default.
"""

from __future__ import annotations

from dataclasses import dataclass

from onboard.etcs.movement_authority import EtcsLevel, MovementAuthority
from trackdb import BaliseGroup, TrackMap
from trackdb.schema import (
    BalisePacket,
    GradientPacket,
    LevelTransitionPacket,
    LinkingPacket,
    LinkReaction,
    MovementAuthorityPacket,
    StaticSpeedProfilePacket,
)

__all__ = [
    "DEFAULT_SYSTEM_VERSION",
    "BaliseGroupReading",
    "LevelTransition",
    "LinkedGroup",
    "TelegramHeader",
    "balise_groups_passed",
    "read_balise_group",
]

DEFAULT_SYSTEM_VERSION = 32
"""M_VERSION of the telegrams: system version 2.0, coded X·16 + Y."""


@dataclass(frozen=True, kw_only=True)
class TelegramHeader:
    """The header of a balise telegram (SUBSET-026 §8.4.2.1), as the VC forwards it."""

    q_updown: int = 1
    """1: up-link telegram, track to train."""
    m_version: int = DEFAULT_SYSTEM_VERSION
    q_media: int = 0
    """0: balise."""
    n_pig: int = 0
    """Position of the balise in the group, from 0."""
    n_total: int = 0
    """Balises in the group, minus one."""
    m_dup: int = 0
    """0: no duplicate."""
    m_mcount: int = 0
    """Message counter of the group's telegrams."""
    nid_c: int = 0
    """Country or region code."""
    nid_bg: int
    """Identity of the balise group."""
    q_link: int
    """1: the group is linked (announced by linking information)."""


@dataclass(frozen=True, kw_only=True)
class LinkedGroup:
    """A group announced by linking (packet 5): where and how surely it should be met."""

    balise_group_id: int
    location_m: float
    reaction: LinkReaction
    location_accuracy_m: float


@dataclass(frozen=True, kw_only=True)
class LevelTransition:
    """A level transition order (packet 41): the new level from ``location_m`` [m] on."""

    location_m: float
    level: EtcsLevel


@dataclass(frozen=True, kw_only=True)
class BaliseGroupReading:
    """What passing a balise group delivered. Locations [m] in the onboard's track coordinate."""

    balise_group_id: int
    location_m: float
    time_s: float
    header: TelegramHeader
    packets: tuple[BalisePacket, ...]
    movement_authority: MovementAuthority | None
    """The Level 1 MA (packet 12), referenced to the group's chainage."""
    static_speed_profile_end_m: float | None
    """Where the SSP sent (packet 27) ends; None if the group sent none."""
    gradient_end_m: float | None
    """Where the gradient profile sent (packet 21) ends; None if the group sent none."""
    level_transition: LevelTransition | None
    linked_groups: tuple[LinkedGroup, ...]


def read_balise_group(
    group: BaliseGroup,
    *,
    location_m: float,
    time_s: float,
    linked: bool,
    country_id: int = 0,
    message_counter: int = 0,
    system_version: int = DEFAULT_SYSTEM_VERSION,
) -> BaliseGroupReading:
    """Decode a group read at ``location_m`` [m] (its chainage, unwrapped) at ``time_s`` [s]."""
    authority: MovementAuthority | None = None
    ssp_end_m: float | None = None
    gradient_end_m: float | None = None
    transition: LevelTransition | None = None
    linked_groups: list[LinkedGroup] = []
    for packet in group.packets:
        if isinstance(packet, MovementAuthorityPacket):
            authority = MovementAuthority.from_packet(packet, reference_m=group.position_m)
        elif isinstance(packet, StaticSpeedProfilePacket):
            ssp_end_m = location_m + packet.length_m
        elif isinstance(packet, GradientPacket):
            gradient_end_m = location_m + packet.length_m
        elif isinstance(packet, LevelTransitionPacket):
            transition = LevelTransition(
                location_m=location_m + packet.distance_m, level=EtcsLevel(packet.level)
            )
        elif isinstance(packet, LinkingPacket):
            linked_groups.extend(
                LinkedGroup(
                    balise_group_id=link.balise_group_id,
                    location_m=location_m + link.distance_m,
                    reaction=link.reaction,
                    location_accuracy_m=link.location_accuracy_m,
                )
                for link in packet.links
            )
    header = TelegramHeader(
        m_version=system_version,
        m_mcount=message_counter % 256,
        nid_c=country_id,
        nid_bg=group.id,
        q_link=1 if linked else 0,
    )
    return BaliseGroupReading(
        balise_group_id=group.id,
        location_m=location_m,
        time_s=time_s,
        header=header,
        packets=group.packets,
        movement_authority=authority,
        static_speed_profile_end_m=ssp_end_m,
        gradient_end_m=gradient_end_m,
        level_transition=transition,
        linked_groups=tuple(linked_groups),
    )


def balise_groups_passed(
    track_map: TrackMap, from_m: float, to_m: float
) -> list[tuple[BaliseGroup, float]]:
    """The groups whose location lies in ``(from_m, to_m]`` [m] of the track coordinate.

    Each with its location in that coordinate, in the order a train running forward meets
    them. Empty when ``to_m ≤ from_m`` (standstill or running back).
    """
    if not to_m > from_m:
        return []
    ahead = track_map.balise_groups_ahead(from_m, to_m - from_m)
    return [(group, from_m + distance_m) for group, distance_m in ahead if distance_m > 0.0]
