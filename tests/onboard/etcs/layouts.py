"""Small lines and onboard set-ups for the ETCS tests.

- ``level_line``: an open, level, straight line of constant line speed, Level 1 or 2, with
  balise groups where asked (each linking the next, as the builder does).
- ``in_full_supervision``: an onboard at a position with a radio MA to an EoA, in FS.
"""

from __future__ import annotations

from functools import cache

from onboard.etcs import EtcsLevel, EtcsOnboard, MovementAuthority, NationalValues
from trackdb import LineBuilder, TrackMap

__all__ = ["DT_S", "in_full_supervision", "level_line"]

DT_S = 0.1


@cache
def level_line(
    *,
    length_m: float = 30_000.0,
    speed_kmh: float = 200.0,
    level: int = 2,
    groups: tuple[tuple[int, float, float | None], ...] = (),
) -> TrackMap:
    """``groups``: (NID_BG, chainage [m], MA length [m] or None) for each balise group."""
    builder = LineBuilder(id="level", name="Level line", etcs_level=level)
    builder.straight(length_m, speed_kmh=speed_kmh)
    for group_id, position_m, authority_m in groups:
        builder.balise_group(group_id, position_m, authority_m=authority_m)
    return TrackMap(builder.build(geodetic_step_m=1000.0))


def in_full_supervision(
    track_map: TrackMap,
    *,
    position_m: float,
    end_of_authority_m: float,
    national: NationalValues | None = None,
    release_speed_mps: float | None = None,
) -> EtcsOnboard:
    """An onboard at ``position_m`` in FS with a Level 2 MA from chainage 0 to the EoA."""
    etcs = EtcsOnboard(
        track_map,
        position_m=position_m,
        national=national or NationalValues(),
        level=EtcsLevel.LEVEL_2,
    )
    etcs.receive_movement_authority(
        MovementAuthority(
            reference_m=0.0,
            end_of_authority_m=end_of_authority_m,
            release_speed_mps=release_speed_mps,
        ),
        0.0,
    )
    return etcs
