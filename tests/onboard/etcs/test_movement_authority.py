"""Movement authorities: SvL, timers, shortening and extension, track description, errors."""

from __future__ import annotations

import pytest

from onboard.etcs import (
    AuthorityInForce,
    EtcsLevel,
    EtcsOnboard,
    MaChange,
    MaSection,
    MovementAuthority,
    MovementAuthorityError,
    OnSightArea,
)
from protocol.messages import EtcsMode
from tests.onboard.etcs.layouts import in_full_supervision, level_line
from trackdb import TrackMap
from trackdb.schema import MovementAuthorityPacket
from trackdb.seed_lines import bologna_ring_level_2


def _in_force(authority: MovementAuthority, reference_m: float = 100.0) -> AuthorityInForce:
    return AuthorityInForce.resolve(authority, reference_location_m=reference_m, now_s=0.0)


def test_supervised_location_is_overlap_then_danger_point_then_end_of_authority() -> None:
    plain = _in_force(MovementAuthority(reference_m=0.0, end_of_authority_m=1_000.0))
    assert plain.end_of_authority_m == plain.supervised_location_m == 1_100.0
    danger = _in_force(
        MovementAuthority(reference_m=0.0, end_of_authority_m=1_000.0, danger_point_m=50.0)
    )
    assert danger.supervised_location_m == 1_150.0
    overlap = _in_force(
        MovementAuthority(
            reference_m=0.0, end_of_authority_m=1_000.0, danger_point_m=50.0, overlap_m=200.0
        )
    )
    assert overlap.supervised_location_m == 1_300.0


def test_overlap_timer_falls_back_to_the_danger_point() -> None:
    ma = _in_force(
        MovementAuthority(
            reference_m=0.0,
            end_of_authority_m=1_000.0,
            danger_point_m=50.0,
            overlap_m=200.0,
            overlap_timer_s=30.0,
            overlap_timer_start_m=300.0,
        )
    )
    # The timer starts when the max-safe front end passes 300 m before the EoA (800 m).
    assert not ma.update(100.0, min_safe_front_m=700.0, max_safe_front_m=790.0)
    assert not ma.update(110.0, min_safe_front_m=720.0, max_safe_front_m=810.0)
    assert not ma.update(139.0, min_safe_front_m=720.0, max_safe_front_m=810.0)
    assert ma.supervised_location_m == 1_300.0
    assert ma.update(140.0, min_safe_front_m=720.0, max_safe_front_m=810.0)
    assert ma.supervised_location_m == 1_150.0


def test_section_timer_shortens_the_authority_unless_stopped_in_time() -> None:
    sections = (
        MaSection(length_m=400.0),
        MaSection(length_m=600.0, timer_s=60.0, timer_stop_m=100.0),
    )
    authority = MovementAuthority(
        reference_m=0.0, end_of_authority_m=1_000.0, overlap_m=100.0, sections=sections
    )
    expired = _in_force(authority)
    assert not expired.update(59.0, min_safe_front_m=300.0, max_safe_front_m=320.0)
    assert expired.update(60.0, min_safe_front_m=300.0, max_safe_front_m=320.0)
    assert expired.end_of_authority_m == expired.supervised_location_m == 500.0
    stopped = _in_force(authority)
    assert not stopped.update(30.0, min_safe_front_m=600.0, max_safe_front_m=620.0)
    assert not stopped.update(90.0, min_safe_front_m=650.0, max_safe_front_m=670.0)
    assert stopped.end_of_authority_m == 1_100.0


def test_extension_and_shortening_by_new_authorities() -> None:
    etcs = in_full_supervision(level_line(), position_m=1_000.0, end_of_authority_m=3_000.0)
    assert etcs.step(0.1, 1_000.0, 0.0).end_of_authority_m == 3_000.0

    def send(eoa_m: float, now_s: float) -> MaChange:
        return etcs.receive_movement_authority(
            MovementAuthority(reference_m=0.0, end_of_authority_m=eoa_m), now_s
        )

    assert send(5_000.0, 0.2) is MaChange.EXTENDED
    assert send(5_000.0, 0.3) is MaChange.UNCHANGED
    assert send(2_000.0, 0.4) is MaChange.SHORTENED
    out = etcs.step(0.5, 1_000.0, 50.0)
    assert out.end_of_authority_m == 2_000.0
    assert out.service_brake or out.emergency_brake  # 180 km/h, 1 km before the new EoA
    # Shortened behind the train: trip.
    send(900.0, 0.6)
    assert etcs.mode is EtcsMode.TR


def test_authority_is_held_at_the_end_of_the_track_description() -> None:
    etcs = EtcsOnboard(level_line(), position_m=100.0)
    etcs.receive_movement_authority(
        MovementAuthority(reference_m=0.0, end_of_authority_m=5_000.0, overlap_m=100.0),
        0.0,
        track_description_m=3_000.0,
    )
    out = etcs.step(0.1, 100.0, 0.0)
    assert out.end_of_authority_m == 3_000.0
    assert out.supervised_location_distance_m == pytest.approx(
        3_000.0 - out.odometry.max_safe_front_m
    )


def test_level_1_packet_becomes_a_level_1_authority() -> None:
    packet = MovementAuthorityPacket(end_of_authority_m=800.0, overlap_m=50.0)
    ma = MovementAuthority.from_packet(packet, reference_m=150.0)
    assert (ma.level, ma.reference_m, ma.end_of_authority_m, ma.overlap_m) == (
        EtcsLevel.LEVEL_1,
        150.0,
        800.0,
        50.0,
    )


@pytest.mark.parametrize(
    "fields",
    [
        {"end_of_authority_m": 0.0},
        {"end_of_authority_m": float("inf")},
        {"end_of_authority_m": 100.0, "overlap_m": -1.0},
        {"end_of_authority_m": 100.0, "danger_point_m": 50.0, "overlap_m": 20.0},
        {"end_of_authority_m": 100.0, "release_speed_mps": -1.0},
        {"end_of_authority_m": 100.0, "sections": (MaSection(length_m=50.0),)},
        {"end_of_authority_m": 100.0, "overlap_timer_s": float("nan")},
    ],
)
def test_bad_authorities_are_refused(fields: dict[str, object]) -> None:
    with pytest.raises(MovementAuthorityError):
        MovementAuthority(reference_m=0.0, **fields)  # type: ignore[arg-type]


def test_bad_sections_and_areas_are_refused() -> None:
    with pytest.raises(MovementAuthorityError):
        MaSection(length_m=0.0)
    with pytest.raises(MovementAuthorityError):
        MaSection(length_m=10.0, timer_s=-1.0)
    with pytest.raises(MovementAuthorityError):
        OnSightArea(start_m=100.0, end_m=50.0)


def test_on_a_ring_an_ma_referenced_most_of_a_lap_behind_keeps_its_eoa() -> None:
    """An RBC's MA keeps the reference of its first issue through its extensions: late in the
    lap the reference lies most of a lap behind the train, nearer the next lap's. Found by a
    two-train run, where the EoA landed a lap too far and the train ran through it."""
    ring = TrackMap(bologna_ring_level_2())
    etcs = EtcsOnboard(ring, position_m=300.0, level=EtcsLevel.LEVEL_2)
    etcs.receive_movement_authority(
        MovementAuthority(reference_m=300.0, end_of_authority_m=5_350.0), 0.0
    )
    position_m, now_s = 300.0, 0.0
    while position_m < 5_400.0:
        position_m += 100.0
        now_s += 10.0
        etcs.step(now_s, position_m, 10.0)
    assert etcs.step(now_s + 0.1, position_m, 10.0).end_of_authority_m == pytest.approx(5_650.0)
    # Extended to 5950 m, by a message referenced at the first issue's 300 m.
    etcs.receive_movement_authority(
        MovementAuthority(reference_m=300.0, end_of_authority_m=5_650.0), now_s + 0.2
    )
    out = etcs.step(now_s + 0.3, position_m, 10.0)
    assert out.end_of_authority_m == pytest.approx(250.0)  # the chainage: round the lap
    # 550 m ahead of the estimated front end, less its interval: not 6250 m (a lap too far).
    ahead_m = out.supervised_location_distance_m
    assert ahead_m is not None
    assert 500.0 < ahead_m < 550.0
