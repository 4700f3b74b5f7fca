"""TrackMap queries: MRSP with TSRs, windows, stopping points, balise groups, geodesy, GPS.

Two small layouts built here: ``open_line`` (1 km, open, S-shaped) and ``ring_line`` (a 1 km
stadium-shaped ring). The seed lines serve the GPS projection properties.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from protocol.units import MPS_PER_KMH
from trackdb import (
    GpsProjection,
    Line,
    LineBuilder,
    NoGeodeticPolylineError,
    SpeedSection,
    TemporarySpeedRestriction,
    TrackDataError,
    TrackMap,
    load_seed_line,
    parse_line,
)
from trackdb.builder import enu_to_geodetic, geodetic_to_enu

SPEED_ATOL_MPS = 1e-9
CHAINAGE_ATOL_M = 1e-6
PROJECTION_ATOL_M = 0.03
RING_CURVE_RADIUS_M = 600.0 / (2.0 * math.pi)


@cache
def open_line() -> Line:
    """1 km open line: east 300 m, left curve, 300 m, right curve; one TSR (200–350 m)."""
    builder = LineBuilder(id="open-km", name="Open kilometre")
    (
        builder.straight(300.0, speed_kmh=72, gradient_permille=2.0)
        .curve(200.0, 500.0, speed_kmh=54)
        .straight(300.0, speed_kmh=72, gradient_permille=-1.0)
        .curve(200.0, -400.0, speed_kmh=72)
    )
    builder.stopping_point("a", "A", 100.0).stopping_point("b", "B", 600.0)
    builder.stopping_point("c", "C", 950.0)
    builder.balise_group(1, 50.0).balise_group(2, 400.0).balise_group(3, 900.0)
    builder.temporary_speed_restriction("works", 200.0, 350.0, speed_kmh=36)
    return builder.build(geodetic_step_m=10.0)


@cache
def ring_line() -> Line:
    """1 km ring: 200 m straights joined by half circles; TSRs on both sides of the origin."""
    half_circle_m = math.pi * RING_CURVE_RADIUS_M
    builder = LineBuilder(id="ring-km", name="Ring kilometre", ring=True)
    (
        builder.straight(200.0, speed_kmh=60)
        .curve(half_circle_m, RING_CURVE_RADIUS_M, speed_kmh=40, gradient_permille=1.0)
        .straight(200.0, speed_kmh=60)
        .curve(half_circle_m, RING_CURVE_RADIUS_M, speed_kmh=40, gradient_permille=-1.0)
    )
    builder.stopping_point("s1", "S1", 100.0).stopping_point("s2", "S2", 600.0)
    builder.balise_group(11, 20.0).balise_group(12, 480.0).balise_group(13, 960.0)
    builder.temporary_speed_restriction("wrap-a", 950.0, 1000.0, speed_kmh=20)
    builder.temporary_speed_restriction("wrap-b", 0.0, 60.0, speed_kmh=20)
    return builder.build(geodetic_step_m=10.0)


@cache
def seed_map(line_id: str) -> TrackMap:
    """Seed line maps, shared: the tests using them do not change their TSRs."""
    return TrackMap(load_seed_line(line_id))


def ring_gap_m(track: TrackMap, a_m: float, b_m: float) -> float:
    """Distance [m] between two chainages, the short way round on a ring."""
    gap = abs(a_m - b_m)
    return min(gap, track.length_m - gap) if track.line.ring else gap


def tsr(id: str, start_m: float, end_m: float, speed_kmh: float) -> TemporarySpeedRestriction:
    return TemporarySpeedRestriction(
        id=id, start_m=start_m, end_m=end_m, speed_mps=speed_kmh * MPS_PER_KMH
    )


# -- chainage and profiles ------------------------------------------------------------------


def test_normalise_wraps_a_ring_and_clamps_an_open_line() -> None:
    ring, line = TrackMap(ring_line()), TrackMap(open_line())
    assert ring.normalise(1250.0) == pytest.approx(250.0, abs=CHAINAGE_ATOL_M)
    assert ring.normalise(-250.0) == pytest.approx(750.0, abs=CHAINAGE_ATOL_M)
    # -1e-17 % 1000 rounds to 1000.0 itself: it must come out as the origin.
    assert ring.normalise(-1e-17) == 0.0
    assert ring.speed_limit_mps(-1e-17) == pytest.approx(60 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert line.normalise(-5.0) == 0.0
    assert line.normalise(1e6) < line.length_m
    assert line.normalise(1e6) == pytest.approx(line.length_m, abs=CHAINAGE_ATOL_M)


def test_profiles_on_both_layouts() -> None:
    line, ring = TrackMap(open_line()), TrackMap(ring_line())
    assert line.gradient_permille(150.0) == pytest.approx(2.0, abs=1e-12)
    assert line.gradient_permille(5000.0) == pytest.approx(0.0, abs=1e-12)
    assert line.curvature_per_m(400.0) == pytest.approx(1 / 500.0, abs=1e-12)
    assert line.curvature_per_m(900.0) == pytest.approx(-1 / 400.0, abs=1e-12)
    assert line.curve_radius_m(900.0) == pytest.approx(400.0, abs=1e-9)
    assert line.curve_radius_m(100.0) == math.inf
    assert ring.curve_radius_m(1300.0) == pytest.approx(RING_CURVE_RADIUS_M, abs=1e-9)
    assert ring.gradient_permille(-100.0) == pytest.approx(-1.0, abs=1e-12)


# -- TSRs and the MRSP ----------------------------------------------------------------------


def test_mrsp_is_the_lowest_of_ssp_and_tsrs() -> None:
    track = TrackMap(open_line())
    expected_kmh = {100.0: 72, 199.9: 72, 200.0: 36, 349.9: 36, 350.0: 54, 499.9: 54, 600.0: 72}
    for chainage_m, speed_kmh in expected_kmh.items():
        assert track.mrsp_mps(chainage_m) == pytest.approx(
            speed_kmh * MPS_PER_KMH, abs=SPEED_ATOL_MPS
        )
    assert track.speed_limit_mps(250.0) == pytest.approx(72 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert track.mrsp_mps(-10.0) == pytest.approx(72 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert track.mrsp_mps(1e6) == pytest.approx(72 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)


def test_tsrs_added_overlapping_replaced_and_revoked() -> None:
    track = TrackMap(open_line())
    track.add_temporary_speed_restriction(tsr("slow", 250.0, 450.0, 18))
    track.add_temporary_speed_restriction(tsr("loose", 0.0, 1000.0, 100))  # above the SSP
    assert track.mrsp_mps(225.0) == pytest.approx(36 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert track.mrsp_mps(300.0) == pytest.approx(18 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert track.mrsp_mps(449.0) == pytest.approx(18 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert track.mrsp_mps(450.0) == pytest.approx(54 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert track.mrsp_mps(700.0) == pytest.approx(72 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert [r.id for r in track.temporary_speed_restrictions] == ["works", "slow", "loose"]

    track.add_temporary_speed_restriction(tsr("slow", 250.0, 300.0, 27))  # same id: replaces
    assert track.mrsp_mps(400.0) == pytest.approx(54 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert track.mrsp_mps(275.0) == pytest.approx(27 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert len(track.temporary_speed_restrictions) == 3

    assert track.revoke_temporary_speed_restriction("works")
    assert not track.revoke_temporary_speed_restriction("works")
    assert track.mrsp_mps(225.0) == pytest.approx(72 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    assert track.mrsp_mps(275.0) == pytest.approx(27 * MPS_PER_KMH, abs=SPEED_ATOL_MPS)
    # The line itself is unchanged, and so is its version.
    assert track.version == open_line().version()
    assert len(track.line.temporary_speed_restrictions) == 1


@pytest.mark.parametrize(("start_m", "end_m"), [(500.0, 1000.5), (300.0, 300.0), (400.0, 200.0)])
def test_a_tsr_off_the_line_is_refused(start_m: float, end_m: float) -> None:
    track = TrackMap(open_line())
    with pytest.raises(ValueError, match="not a range on line"):
        track.add_temporary_speed_restriction(tsr("bad", start_m, end_m, 30))
    assert [r.id for r in track.temporary_speed_restrictions] == ["works"]


def test_mrsp_window_on_the_open_line() -> None:
    track = TrackMap(open_line())
    sections = track.mrsp_window(100.0, 500.0)
    expected = [(0.0, 100.0, 72), (100.0, 250.0, 36), (250.0, 400.0, 54), (400.0, 500.0, 72)]
    assert len(sections) == len(expected)
    for section, (from_m, to_m, speed_kmh) in zip(sections, expected, strict=True):
        assert isinstance(section, SpeedSection)
        assert_allclose(section, (from_m, to_m, speed_kmh * MPS_PER_KMH), atol=CHAINAGE_ATOL_M)
    # The window stops at the line's end; from the end (or beyond) nothing lies ahead.
    tail = track.mrsp_window(900.0, 500.0)
    assert_allclose(tail, [(0.0, 100.0, 72 * MPS_PER_KMH)], atol=CHAINAGE_ATOL_M)
    assert track.mrsp_window(1000.0, 100.0) == []
    assert track.mrsp_window(2000.0, 100.0) == []
    assert track.mrsp_window(500.0, 0.0) == []
    head = track.mrsp_window(-50.0, 100.0)  # clamped to the origin
    assert_allclose(head, [(0.0, 100.0, 72 * MPS_PER_KMH)], atol=CHAINAGE_ATOL_M)
    with pytest.raises(ValueError, match="not a finite length"):
        track.mrsp_window(0.0, -1.0)


def test_mrsp_window_runs_across_the_ring_origin_and_merges() -> None:
    track = TrackMap(ring_line())
    sections = track.mrsp_window(900.0, 300.0)
    # 900–950 curve at 40; 950–1000 and 0–60 under TSRs at 20 (one section); 60–200 at 60.
    expected = [
        (0.0, 50.0, 40 * MPS_PER_KMH),
        (50.0, 160.0, 20 * MPS_PER_KMH),
        (160.0, 300.0, 60 * MPS_PER_KMH),
    ]
    assert_allclose(sections, expected, atol=CHAINAGE_ATOL_M)
    laps = track.mrsp_window(0.0, 2500.0)
    assert laps[-1].to_distance_m == pytest.approx(2500.0, abs=CHAINAGE_ATOL_M)
    # Six steps per lap, of which the 20 km/h steps on each side of the origin merge.
    assert len(laps) == 13


def test_mrsp_ahead_samples_like_the_point_query() -> None:
    for track in (TrackMap(open_line()), TrackMap(ring_line())):
        distances_m = np.linspace(-1500.0, 2500.0, 4001)
        expected = [track.mrsp_mps(940.0 + distance) for distance in distances_m.tolist()]
        assert_allclose(track.mrsp_ahead_mps(940.0, distances_m), expected, atol=SPEED_ATOL_MPS)
    ring = TrackMap(ring_line())
    assert_allclose(ring.mrsp_ahead_mps(0.0, -1e-17), 20 * MPS_PER_KMH, atol=SPEED_ATOL_MPS)
    grid = ring.mrsp_ahead_mps(900.0, [[0.0, 100.0], [200.0, 300.0]])
    assert_allclose(
        grid,
        [[40 * MPS_PER_KMH, 20 * MPS_PER_KMH], [60 * MPS_PER_KMH, 40 * MPS_PER_KMH]],
        atol=SPEED_ATOL_MPS,
    )


tsr_lists = st.lists(
    st.tuples(
        st.floats(0.0, 990.0),
        st.floats(1.0, 1000.0),
        st.sampled_from([10.0, 20.0, 30.0, 45.0, 100.0]),
    ),
    max_size=5,
)


def _with_tsrs(line: Line, tsrs: list[tuple[float, float, float]]) -> TrackMap:
    track = TrackMap(line)
    for index, (start_m, length_m, speed_kmh) in enumerate(tsrs):
        end_m = min(start_m + length_m, line.length_m)
        track.add_temporary_speed_restriction(tsr(f"t{index}", start_m, end_m, speed_kmh))
    return track


@settings(max_examples=60)
@given(
    tsrs=tsr_lists,
    ring=st.booleans(),
    chainage_m=st.floats(-2000.0, 3000.0, allow_nan=False),
)
def test_mrsp_is_the_minimum_over_what_is_in_force(
    tsrs: list[tuple[float, float, float]], ring: bool, chainage_m: float
) -> None:
    track = _with_tsrs(ring_line() if ring else open_line(), tsrs)
    position_m = track.normalise(chainage_m)
    expected = min(
        [track.speed_limit_mps(position_m)]
        + [
            r.speed_mps
            for r in track.temporary_speed_restrictions
            if r.start_m <= position_m < r.end_m
        ]
    )
    assert track.mrsp_mps(chainage_m) == pytest.approx(expected, abs=SPEED_ATOL_MPS)


@settings(max_examples=60)
@given(
    tsrs=tsr_lists,
    ring=st.booleans(),
    start_m=st.floats(-500.0, 1500.0),
    length_m=st.floats(0.0, 2500.0),
    samples=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20),
)
def test_mrsp_window_is_contiguous_and_agrees_with_the_point_query(
    tsrs: list[tuple[float, float, float]],
    ring: bool,
    start_m: float,
    length_m: float,
    samples: list[float],
) -> None:
    track = _with_tsrs(ring_line() if ring else open_line(), tsrs)
    sections = track.mrsp_window(start_m, length_m)
    origin_m = start_m if ring else min(max(start_m, 0.0), track.length_m)
    covered_m = length_m if ring else min(length_m, track.length_m - origin_m)
    if covered_m == 0.0:
        assert sections == []
        return
    assert sections[0].from_distance_m == 0.0
    assert sections[-1].to_distance_m == pytest.approx(covered_m, abs=CHAINAGE_ATOL_M)
    for before, after in zip(sections, sections[1:], strict=False):
        assert before.to_distance_m == after.from_distance_m
        assert before.speed_mps != after.speed_mps
    for section in sections:
        assert section.to_distance_m > section.from_distance_m
        span_m = section.to_distance_m - section.from_distance_m
        for fraction in [0.5, *samples]:
            distance_m = section.from_distance_m + fraction * span_m
            if min(distance_m - section.from_distance_m, section.to_distance_m - distance_m) < 1e-6:
                continue  # a boundary: either side's speed is right up to rounding
            assert track.mrsp_mps(origin_m + distance_m) == pytest.approx(
                section.speed_mps, abs=SPEED_ATOL_MPS
            )


# -- stopping points and balise groups ------------------------------------------------------


def test_next_stopping_point_on_the_open_line() -> None:
    track = TrackMap(open_line())
    found = track.next_stopping_point(600.0)
    assert found is not None
    assert found[0].id == "b"
    assert found[1] == 0.0  # a point at the chainage itself
    found = track.next_stopping_point(600.1)
    assert found is not None
    assert found[0].id == "c"
    assert found[1] == pytest.approx(349.9, abs=CHAINAGE_ATOL_M)
    found = track.next_stopping_point(-50.0)  # clamped to the origin
    assert found is not None
    assert found[0].id == "a"
    assert found[1] == pytest.approx(100.0, abs=CHAINAGE_ATOL_M)
    assert track.next_stopping_point(600.1, max_distance_m=300.0) is None
    assert track.next_stopping_point(951.0) is None
    assert track.next_stopping_point(5000.0) is None


def test_next_stopping_point_wraps_on_the_ring() -> None:
    track = TrackMap(ring_line())
    found = track.next_stopping_point(650.0)
    assert found is not None
    assert found[0].id == "s1"
    assert found[1] == pytest.approx(450.0, abs=CHAINAGE_ATOL_M)
    found = track.next_stopping_point(-10.0)
    assert found is not None
    assert found[0].id == "s1"
    assert found[1] == pytest.approx(110.0, abs=CHAINAGE_ATOL_M)
    assert track.next_stopping_point(650.0, max_distance_m=449.0) is None
    empty = TrackMap(load_seed_line("bologna-ring").model_copy(update={"stopping_points": ()}))
    assert empty.next_stopping_point(0.0) is None


def test_balise_groups_ahead() -> None:
    line, ring = TrackMap(open_line()), TrackMap(ring_line())

    def ahead(track: TrackMap, chainage_m: float, distance_m: float) -> list[tuple[int, float]]:
        return [(group.id, d) for group, d in track.balise_groups_ahead(chainage_m, distance_m)]

    assert ahead(line, 50.0, 350.0) == [(1, 0.0), (2, pytest.approx(350.0, abs=1e-9))]
    assert ahead(line, 50.1, 349.8) == []
    assert ahead(line, 500.0, 5000.0) == [(3, pytest.approx(400.0, abs=1e-9))]
    assert ahead(line, 950.0, 5000.0) == []
    assert ahead(ring, 900.0, 200.0) == [
        (13, pytest.approx(60.0, abs=1e-9)),
        (11, pytest.approx(120.0, abs=1e-9)),
    ]
    laps = ahead(ring, 0.0, 2000.0)
    assert [group for group, _ in laps] == [11, 12, 13, 11, 12, 13]
    assert_allclose([d for _, d in laps], [20, 480, 960, 1020, 1480, 1960], atol=1e-9)


# -- geodesy and GPS projection -------------------------------------------------------------


def test_geodetic_interpolates_the_polyline() -> None:
    line = open_line()
    track = TrackMap(line)
    first, second = line.geodetic[0], line.geodetic[1]
    middle_m = (first.chainage_m + second.chainage_m) / 2.0
    assert_allclose(
        track.geodetic_at(middle_m),
        (
            (first.latitude_deg + second.latitude_deg) / 2.0,
            (first.longitude_deg + second.longitude_deg) / 2.0,
            (first.altitude_m + second.altitude_m) / 2.0,
        ),
        atol=1e-12,
    )
    assert track.altitude_m(150.0) == pytest.approx(50.0 + 0.3, abs=1e-9)  # 2 ‰ over 150 m
    last = line.geodetic[-1]
    end = (last.latitude_deg, last.longitude_deg, last.altitude_m)
    start = (first.latitude_deg, first.longitude_deg, first.altitude_m)
    assert_allclose(track.geodetic_at(5000.0), end, atol=1e-9)
    assert_allclose(track.geodetic_at(-5.0), start, atol=1e-12)
    ring = TrackMap(ring_line())
    assert_allclose(ring.geodetic_at(1250.0), ring.geodetic_at(250.0), atol=1e-9)
    assert ring.altitude_m(-300.0) == pytest.approx(ring.altitude_m(700.0), abs=1e-9)


def _offset_fix(track: TrackMap, chainage_m: float, left_m: float) -> tuple[float, float]:
    """A fix ``left_m`` [m] to the left of the first straight (heading east) of open_line."""
    origin = track.line.geodetic[0]
    return enu_to_geodetic(chainage_m, left_m, origin.latitude_deg, origin.longitude_deg)


def test_projection_gives_chainage_and_signed_cross_track() -> None:
    track = TrackMap(open_line())
    for left_m in (4.0, -3.0):
        fix = _offset_fix(track, 123.0, left_m)
        for near_m in (None, 150.0):
            projection = track.project(*fix, near_m=near_m)
            assert isinstance(projection, GpsProjection)
            assert projection.chainage_m == pytest.approx(123.0, abs=PROJECTION_ATOL_M)
            assert projection.cross_track_m == pytest.approx(left_m, abs=PROJECTION_ATOL_M)
            assert projection.bounded is (near_m is not None)
    before_start = track.project(*_offset_fix(track, -20.0, 0.0), near_m=0.0)
    assert before_start.chainage_m == 0.0
    assert before_start.bounded
    assert before_start.cross_track_m == pytest.approx(20.0, abs=PROJECTION_ATOL_M)


def test_a_far_fix_falls_back_to_the_global_search() -> None:
    track = TrackMap(open_line())
    lat, lon, _ = track.geodetic_at(700.0)
    # The estimate is 600 m behind: the bounded best point is at the window's edge.
    behind = track.project(lat, lon, near_m=100.0, window_m=100.0)
    assert behind.chainage_m == pytest.approx(700.0, abs=PROJECTION_ATOL_M)
    assert not behind.bounded
    # A fix 80 m off the track is checked globally, and is found where it is.
    off = track.project(*_offset_fix(track, 150.0, 80.0), near_m=150.0)
    assert off.chainage_m == pytest.approx(150.0, abs=PROJECTION_ATOL_M)
    assert not off.bounded
    ring = TrackMap(ring_line())
    lat, lon, _ = ring.geodetic_at(20.0)
    across = ring.project(lat, lon, near_m=600.0, window_m=100.0)
    assert across.chainage_m == pytest.approx(20.0, abs=PROJECTION_ATOL_M)
    assert not across.bounded
    wrapped = ring.project(lat, lon, near_m=980.0, window_m=100.0)
    assert wrapped.chainage_m == pytest.approx(20.0, abs=PROJECTION_ATOL_M)
    assert wrapped.bounded


def test_a_window_wider_than_the_ring_searches_all_of_it() -> None:
    ring = TrackMap(ring_line())
    lat, lon, _ = ring.geodetic_at(333.0)
    projection = ring.project(lat, lon, near_m=800.0, window_m=600.0)
    assert projection.chainage_m == pytest.approx(333.0, abs=PROJECTION_ATOL_M)
    assert projection.bounded


def test_geodetic_queries_need_a_polyline() -> None:
    track = TrackMap(parse_line(open_line().model_dump() | {"geodetic": []}))
    for query in (lambda: track.altitude_m(1.0), lambda: track.geodetic_at(1.0)):
        with pytest.raises(NoGeodeticPolylineError):
            query()
    with pytest.raises(TrackDataError, match="no geodetic polyline"):
        track.project(44.5, 11.3)
    with pytest.raises(ValueError, match="not finite"):
        TrackMap(open_line()).project(math.nan, 11.3)


@settings(max_examples=150, deadline=None)
@given(
    line_id=st.sampled_from(["bologna-ring", "milano-bologna"]),
    fraction=st.floats(0.0, 1.0, exclude_max=True),
    estimate_error_m=st.floats(-200.0, 200.0),
    bounded=st.booleans(),
)
def test_projection_recovers_the_chainage_of_a_point_on_the_track(
    line_id: str, fraction: float, estimate_error_m: float, bounded: bool
) -> None:
    track = seed_map(line_id)
    chainage_m = fraction * track.length_m
    lat, lon, _ = track.geodetic_at(chainage_m)
    near_m = chainage_m + estimate_error_m if bounded else None
    projection = track.project(lat, lon, near_m=near_m)
    assert ring_gap_m(track, projection.chainage_m, chainage_m) <= PROJECTION_ATOL_M
    assert abs(projection.cross_track_m) <= PROJECTION_ATOL_M
    assert projection.bounded is bounded
    assert 0.0 <= projection.chainage_m < track.length_m


@settings(max_examples=100, deadline=None)
@given(
    line_id=st.sampled_from(["bologna-ring", "milano-bologna"]),
    fraction=st.floats(0.001, 0.999),
    noise_m=st.floats(0.0, 5.0),
    bearing_rad=st.floats(0.0, 2.0 * math.pi),
)
def test_a_noisy_fix_projects_within_its_noise(
    line_id: str, fraction: float, noise_m: float, bearing_rad: float
) -> None:
    track = seed_map(line_id)
    chainage_m = fraction * track.length_m
    lat, lon, _ = track.geodetic_at(chainage_m)
    # The noise is added in the plane TrackMap projects in: east/north from the first point.
    origin = (track.line.geodetic[0].latitude_deg, track.line.geodetic[0].longitude_deg)
    east_m, north_m = geodetic_to_enu(lat, lon, *origin)
    noisy = enu_to_geodetic(
        east_m + noise_m * math.cos(bearing_rad), north_m + noise_m * math.sin(bearing_rad), *origin
    )
    for near_m in (None, chainage_m + 30.0):
        projection = track.project(*noisy, near_m=near_m)
        # On a curve of radius R an offset d moves the foot point by up to d·R/(R−d).
        assert ring_gap_m(track, projection.chainage_m, chainage_m) <= noise_m * 1.02 + 0.05
        assert abs(projection.cross_track_m) <= noise_m + 0.05


def test_distance_beyond_the_last_balise_group() -> None:
    line = (
        LineBuilder(id="groups", name="Groups")
        .straight(2000.0, speed_kmh=80)
        .balise_group(1, 300.0)
        .balise_group(2, 1200.0, link_next=False)
        .build()
    )
    track_map = TrackMap(line)
    assert track_map.distance_beyond_balise_group_m(100.0) is None  # before the first group
    assert track_map.distance_beyond_balise_group_m(300.0) == 0.0
    assert track_map.distance_beyond_balise_group_m(1000.0) == pytest.approx(700.0)
    assert track_map.distance_beyond_balise_group_m(1900.0) == pytest.approx(700.0)
    ring = TrackMap(load_seed_line("bologna-ring"))
    first = min(group.position_m for group in ring.line.balise_groups)
    last = max(group.position_m for group in ring.line.balise_groups)
    # Before the first group of a lap, the last group of the previous lap counts.
    assert ring.distance_beyond_balise_group_m(first / 2.0) == pytest.approx(
        first / 2.0 + ring.length_m - last
    )
    bare = TrackMap(LineBuilder(id="bare", name="Bare").straight(500.0, speed_kmh=40).build())
    assert bare.distance_beyond_balise_group_m(250.0) is None
