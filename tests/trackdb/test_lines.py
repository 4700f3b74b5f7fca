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


def test_version_is_a_content_hash() -> None:
    assert load_seed_line("bologna-ring").version() == load_seed_line("bologna-ring").version()
    assert _line().version() != _line(name="Other").version()
    assert len(_line().version()) == 64


@pytest.mark.parametrize(
    "overrides, problem",
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
        ({"stopping_points": [{"id": "x", "name": "X", "position_m": 1000.0}]}, "beyond"),
    ],
)
def test_invalid_lines_list_their_problems(overrides: dict[str, object], problem: str) -> None:
    with pytest.raises(LineValidationError) as caught:
        _line(**overrides)
    assert any(problem in item for item in caught.value.problems), caught.value.problems


def test_track_map_lookups_and_ring_wrap() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    assert ring.curve_radius_m(100.0) == math.inf
    assert ring.curve_radius_m(1000.0) == 450.0
    assert ring.gradient_permille(700.0) == 4.0
    assert ring.gradient_permille(700.0 + ring.length_m) == 4.0
    assert ring.normalise(-1.0) == pytest.approx(ring.length_m - 1.0)
    assert ring.speed_limit_mps(1000.0) == pytest.approx(60 / 3.6)


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
    with pytest.raises(ValueError):
        ProfileSection(start_m=0.0, end_m=math.inf, value=1.0)
