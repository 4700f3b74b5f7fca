"""Line schema validation, the seed line and TrackMap look-ups."""

from __future__ import annotations

import math

import pytest

from trackdb import Line, LineValidationError, ProfileSection, TrackMap, load_seed_line, parse_line


def _line(**overrides: object) -> Line:
    document: dict[str, object] = {
        "id": "tiny",
        "name": "Tiny",
        "length_m": 1000.0,
        "gradient_permille": [{"start_m": 0, "end_m": 1000, "value": 2.0}],
        "speed_limit_mps": [
            {"start_m": 0, "end_m": 400, "value": 20.0},
            {"start_m": 400, "end_m": 1000, "value": 10.0},
        ],
    }
    return parse_line(document | overrides)


def test_seed_ring_is_plausible() -> None:
    line = load_seed_line("bologna-ring")
    assert line.ring
    assert 5500 <= line.length_m <= 5900
    assert len(line.stopping_points) == 3
    assert min(s.value for s in line.speed_limit_mps) * 3.6 > 40.0
    assert max(abs(s.value) for s in line.gradient_permille) <= 10.0
    assert line.etcs_level == 1
    assert any(
        packet.type == "movement_authority"
        for group in line.balise_groups
        for packet in group.packets
    )
    # The ring closes: altitude and position come back to the origin.
    first, last = line.geodetic[0], line.geodetic[-1]
    assert last.altitude_m == pytest.approx(first.altitude_m, abs=1e-6)
    assert (last.latitude_deg, last.longitude_deg) == pytest.approx(
        (first.latitude_deg, first.longitude_deg), abs=1e-7
    )


def test_seed_high_speed_line_is_plausible() -> None:
    line = load_seed_line("milano-bologna")
    assert line.length_m == 200_000.0
    assert max(s.value for s in line.speed_limit_mps) * 3.6 == pytest.approx(300.0)
    assert min(s.value for s in line.speed_limit_mps) * 3.6 < 200.0
    assert max(abs(s.value) for s in line.gradient_permille) <= 15.0
    assert line.stopping_points[0].position_m < 1000
    assert line.stopping_points[-1].position_m > 198_000
    assert len(line.stopping_points) >= 4


def test_version_is_a_content_hash() -> None:
    assert load_seed_line("bologna-ring").version() == load_seed_line("bologna-ring").version()
    assert _line().version() != _line(name="Other").version()
    assert len(_line().version()) == 64


@pytest.mark.parametrize(
    ("overrides", "problem"),
    [
        (
            {"gradient_permille": [{"start_m": 0, "end_m": 900, "value": 0}]},
            "not at the line's end",
        ),
        ({"gradient_permille": [{"start_m": 10, "end_m": 1000, "value": 0}]}, "not 0"),
        (
            {
                "speed_limit_mps": [
                    {"start_m": 0, "end_m": 400, "value": 20.0},
                    {"start_m": 500, "end_m": 1000, "value": 10.0},
                ]
            },
            "gap",
        ),
        (
            {
                "speed_limit_mps": [
                    {"start_m": 0, "end_m": 600, "value": 20.0},
                    {"start_m": 500, "end_m": 1000, "value": 10.0},
                ]
            },
            "before",
        ),
        ({"speed_limit_mps": [{"start_m": 0, "end_m": 1000, "value": 0.0}]}, "non-positive speed"),
        ({"curve_radius_m": [{"start_m": 100, "end_m": 50, "value": 300}]}, "non-positive length"),
        ({"curve_radius_m": [{"start_m": 100, "end_m": 200, "value": 10}]}, "below 50 m"),
        ({"stopping_points": [{"id": "x", "name": "X", "position_m": 1000.0}]}, "beyond"),
        ({"stop_markers": [{"id": "m", "position_m": 1000.0}]}, "stop_markers[0] m: beyond"),
        (
            {"stop_markers": [{"id": "a", "position_m": 300.0}, {"id": "b", "position_m": 200.0}]},
            "not after the previous marker",
        ),
        (
            {"stop_markers": [{"id": "a", "position_m": 100.0}, {"id": "a", "position_m": 200.0}]},
            "stop_markers: duplicate id a",
        ),
    ],
)
def test_invalid_lines_list_their_problems(overrides: dict[str, object], problem: str) -> None:
    with pytest.raises(LineValidationError) as caught:
        _line(**overrides)
    assert any(problem in item for item in caught.value.problems), caught.value.problems


def test_track_map_lookups_and_ring_wrap() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    assert ring.curve_radius_m(100.0) == math.inf
    assert ring.curvature_per_m(100.0) == 0.0
    assert ring.curve_radius_m(1200.0) == 400.0
    assert ring.curvature_per_m(1200.0) == pytest.approx(1 / 400.0)
    assert ring.gradient_permille(700.0) == 2.0
    assert ring.gradient_permille(700.0 + ring.length_m) == 2.0
    assert ring.normalise(-1.0) == pytest.approx(ring.length_m - 1.0)
    assert ring.speed_limit_mps(1200.0) == pytest.approx(60 / 3.6)
    assert ring.speed_limit_mps(700.0) == pytest.approx(80 / 3.6)


def test_track_map_clamps_an_open_line() -> None:
    track = TrackMap(_line())
    assert track.speed_limit_mps(-5.0) == 20.0
    assert track.speed_limit_mps(5000.0) == 10.0
    assert track.gradient_permille(999.999) == 2.0


def test_schema_errors_are_listed_with_their_location() -> None:
    with pytest.raises(LineValidationError) as caught:
        _line(length_m=-1.0, speed_limit_mps="fast")
    assert any(problem.startswith("length_m:") for problem in caught.value.problems)
    assert any(problem.startswith("speed_limit_mps:") for problem in caught.value.problems)


def test_profile_section_rejects_non_finite() -> None:
    with pytest.raises(ValueError, match="finite number"):
        ProfileSection(start_m=0.0, end_m=math.inf, value=1.0)
