"""RailJSON import: the path through every kind of switch, in the right direction on each track
section, and what is mapped along it (profiles, stopping points, markers, balise groups, the
polyline)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from numpy.testing import assert_allclose

from protocol.units import MPS_PER_KMH
from tests.trackdb.railjson_builder import junction_valley, twin_tracks
from trackdb import Line, RailJsonError, TrackMap
from trackdb.builder import geodetic_to_enu
from trackdb.railjson import line_from_railjson, stopping_point_id

COMMITTED = (
    Path(__file__).resolve().parents[2] / "deploy" / "lines" / "junction-valley.railjson.json"
)


def valley(document: dict[str, Any] | None = None, **options: Any) -> Line:
    options = {"from_op": "westbrook", "to_op": "eastfield", "line_id": "jv"} | options
    source = json.dumps(document) if document is not None else junction_valley().dumps()
    return line_from_railjson(source, **options)


def values(sections: Any, scale: float = 1.0) -> list[tuple[float, float, float]]:
    return [(s.start_m, s.end_m, round(s.value * scale, 6)) for s in sections]


def test_the_committed_junction_valley_is_the_builders() -> None:
    assert COMMITTED.read_text(encoding="utf-8") == junction_valley().dumps()


def test_junction_valley_has_what_the_issue_asks_for() -> None:
    document = junction_valley().build()
    assert len(document["track_sections"]) >= 30
    kinds = [switch["switch_type"] for switch in document["switches"]]
    assert len(kinds) >= 10
    assert {"point_switch", "crossing", "double_slip_switch", "link"} <= set(kinds)
    speeds = {
        round(s["speed_limit"] / MPS_PER_KMH)
        for s in document["speed_sections"]
        if s["speed_limit"]
    }
    assert {60, 80, 100} <= speeds
    slopes = [s["gradient"] for t in document["track_sections"] for s in t["slopes"]]
    radii = [abs(c["radius"]) for t in document["track_sections"] for c in t["curves"]]
    assert max(abs(g) for g in slopes) <= 15.0
    assert min(radii) >= 300.0
    assert len(document["detectors"]) >= 10


def test_westbrook_to_eastfield() -> None:
    line = valley()
    assert line.etcs_level == 2
    assert line.name == "Westbrook – Eastfield"
    assert line.length_m == pytest.approx(9600.0)  # 300 m run-in + 9000 m + 300 m overrun
    stops = [(s.id, s.name, s.position_m) for s in line.stopping_points]
    assert stops == [
        ("westbrook", "Westbrook", 300.0),
        ("millbridge", "Millbridge", 2950.0),
        ("valley-junction", "Valley Junction", 6050.0),
        ("eastfield", "Eastfield", 9300.0),
    ]
    assert [(m.id, m.position_m) for m in line.stop_markers] == [
        (f"{stop_id}-marker", position - 30.0) for stop_id, _, position in stops
    ]
    # main-05 and main-06 are stored backwards (their BEGIN at the east): still -8 ‰ downhill
    # eastbound, the right-hand curve still right-hand.
    assert values(line.gradient_permille) == [
        (0.0, 800.0, 0.0), (800.0, 1700.0, 5.0), (1700.0, 3300.0, 0.0),
        (3300.0, 4900.0, -8.0), (4900.0, 6400.0, 0.0), (6400.0, 7300.0, 10.0),
        (7300.0, 8400.0, -6.0), (8400.0, 9600.0, 0.0),
    ]  # fmt: skip
    assert values(line.curve_radius_m) == [
        (1100.0, 1700.0, 1500.0), (4100.0, 4600.0, -800.0), (6800.0, 7300.0, -600.0),
        (7900.0, 8400.0, 600.0),
    ]  # fmt: skip
    # 100 on the main line, 80 in the stations, 60 at the junction; the westbound-only 40 and
    # the freight-only 50 do not apply.
    assert values(line.speed_limit_mps, 1 / MPS_PER_KMH) == [
        (0.0, 2600.0, 100.0), (2600.0, 3300.0, 80.0), (3300.0, 4900.0, 100.0),
        (4900.0, 6400.0, 60.0), (6400.0, 8600.0, 100.0), (8600.0, 9600.0, 80.0),
    ]  # fmt: skip


def test_the_other_way_mirrors_every_profile() -> None:
    east, west = valley(), valley(from_op="eastfield", to_op="westbrook")
    length = east.length_m
    assert west.length_m == pytest.approx(length)
    mirrored = [
        (length - s.end_m, length - s.start_m, -s.value) for s in reversed(east.gradient_permille)
    ]
    assert_allclose(
        [(s.start_m, s.end_m, s.value) for s in west.gradient_permille], mirrored, atol=1e-6
    )
    mirrored = [
        (length - s.end_m, length - s.start_m, -s.value) for s in reversed(east.curve_radius_m)
    ]
    assert_allclose(
        [(s.start_m, s.end_m, s.value) for s in west.curve_radius_m], mirrored, atol=1e-6
    )
    assert [s.id for s in west.stopping_points] == [
        "eastfield",
        "valley-junction",
        "millbridge",
        "westbrook",
    ]
    # Westbound, the STOP_TO_START 40 km/h section on main-08's first 600 m applies.
    assert values(west.speed_limit_mps, 1 / MPS_PER_KMH)[2] == (2600.0, 3200.0, 40.0)


def test_curves_turn_as_the_polyline_does() -> None:
    """Our sign (positive left) agrees with the geometry, both ways and on reversed sections."""
    for line in (valley(), valley(from_op="eastfield", to_op="westbrook")):
        track = TrackMap(line)
        for section in line.curve_radius_m:
            turned = _heading(line, track, section.end_m - 5) - _heading(
                line, track, section.start_m + 5
            )
            turned = (turned + math.pi) % (2 * math.pi) - math.pi
            expected = (section.end_m - section.start_m - 10) / section.value
            # The polyline is straight between vertices 25 m apart: a chord's turn at each end.
            tolerance = 25.0 / abs(section.value)
            assert turned == pytest.approx(expected, abs=tolerance), (line.id, section)


def _heading(line: Line, track: TrackMap, chainage_m: float) -> float:
    origin = line.geodetic[0]
    ahead = [track.geodetic_at(chainage_m + d) for d in (-2.0, 2.0)]
    (e0, n0), (e1, n1) = (
        geodetic_to_enu(lat, lon, origin.latitude_deg, origin.longitude_deg)
        for lat, lon, _ in ahead
    )
    return math.atan2(n1 - n0, e1 - e0)


def test_altitude_follows_the_gradient() -> None:
    line = valley()
    track = TrackMap(line)
    for first, second in zip(line.geodetic, line.geodetic[1:], strict=False):
        climb = sum(
            s.value / 1000.0 * (min(s.end_m, second.chainage_m) - max(s.start_m, first.chainage_m))
            for s in line.gradient_permille
            if s.start_m < second.chainage_m and s.end_m > first.chainage_m
        )
        assert second.altitude_m - first.altitude_m == pytest.approx(climb, abs=1e-6)
    assert min(p.altitude_m for p in line.geodetic) == 0.0
    assert track.geodetic_at(0.0)[2] == pytest.approx(line.geodetic[0].altitude_m)


def test_balise_groups_at_detectors_and_no_more_than_the_spacing_apart() -> None:
    line = valley(balise_spacing_m=800.0)
    positions = [group.position_m for group in line.balise_groups]
    assert positions[:4] == pytest.approx([405.0, 810.0, 1260.0, 1710.0])  # detectors at 810, 1710
    gaps = [b - a for a, b in zip([0.0, *positions], [*positions, line.length_m], strict=False)]
    assert max(gaps) <= 800.0 + 1e-6
    links = [group.packets[0].links[0] for group in line.balise_groups[:-1]]  # type: ignore[union-attr]
    assert [link.balise_group_id for link in links] == [g.id for g in line.balise_groups[1:]]


def test_the_double_slip_and_the_crossing_let_through_what_their_groups_allow() -> None:
    document = junction_valley().build()
    extra = {"east-01": ("east-bay", 100.0), "cross-00": ("north-freight", 100.0),
             "yard-03": ("yard", 100.0)}  # fmt: skip
    lengths = {t["id"]: t["length"] for t in document["track_sections"]}
    for track, (op_id, position) in extra.items():
        document["operational_points"].append(
            {"id": op_id, "parts": [{"track": track, "position": min(position, lengths[track])}]}
        )
    # The double slip's A2 → B1: from the bay track onto main-10 (Eastfield platform 1).
    line = valley(document, from_op="east-bay", to_op="eastfield")
    assert [s.id for s in line.stopping_points][-1] == "eastfield"
    # The crossing's A2 → B2: the freight line goes straight over the main line.
    assert valley(document, from_op="north-freight", to_op="yard").length_m > 2000.0
    # ... but no crossing lets a train turn from one line onto the other.
    with pytest.raises(RailJsonError, match="no path from 'westbrook' to 'yard'"):
        valley(document, to_op="yard")


def test_equal_paths_take_the_first_id_and_via_decides() -> None:
    document = twin_tracks().build()
    speeds = [
        round(s.value / MPS_PER_KMH)
        for s in valley(document, from_op="west", to_op="east").speed_limit_mps
    ]
    assert speeds == [60, 40, 60]  # twin-a sorts before twin-b
    line = valley(document, from_op="west", to_op="east", via=["b-platform"], default_speed_kmh=50)
    assert [round(s.value / MPS_PER_KMH) for s in line.speed_limit_mps] == [50, 80, 50]
    # An operational point with a part on each twin: the one on the path.
    assert [s.id for s in line.stopping_points] == ["west", "middle", "b-platform", "east"]


def test_a_point_switch_never_leads_from_one_branch_to_the_other() -> None:
    document = twin_tracks().build()
    document["operational_points"].append(
        {"id": "a-platform", "parts": [{"track": "twin-a", "position": 300}]}
    )
    with pytest.raises(RailJsonError) as caught:
        valley(document, from_op="a-platform", to_op="b-platform")
    assert caught.value.json_path == "$.operational_points[2]"


def test_speed_tags_pick_their_limits() -> None:
    line = valley(speed_tag="freight")
    assert values(line.speed_limit_mps, 1 / MPS_PER_KMH)[4] == (6400.0, 8600.0, 50.0)


def test_early_3x_documents_with_track_section_links_read_the_same() -> None:
    document = junction_valley().build()
    document["version"] = "3.0.0"
    links = [s for s in document["switches"] if s["switch_type"] == "link"]
    document["switches"] = [s for s in document["switches"] if s["switch_type"] != "link"]
    document["track_section_links"] = [
        {"id": s["id"], "src": s["ports"]["A"], "dst": s["ports"]["B"]} for s in links
    ]
    document["switch_types"] = document.pop("extended_switch_types")
    assert valley(document).version() == valley().version()


@pytest.mark.parametrize(
    ("op_id", "expected"),
    [
        ("westbrook", "westbrook"),
        ("Gare de Saint-Étienne Châteaucreux", "gare-de-saint-etienne-chateaucreux"),
        ("__Bf. Zürich HB/Gl.7", "bf-zurich-hb-gl-7"),
        ("!!!", "op-" + "0d2c4cb6"),
        ("x" * 70, "x" * 48 + "-" + "b0ba36ce"),
    ],
)
def test_stopping_point_ids(op_id: str, expected: str) -> None:
    import hashlib

    if expected.startswith("op-") or len(expected) > 48:
        expected = expected.rsplit("-", 1)[0] + "-" + hashlib.sha256(op_id.encode()).hexdigest()[:8]
    assert stopping_point_id(op_id) == expected


def test_operational_points_whose_ids_meet_get_numbered() -> None:
    document = twin_tracks().build()
    document["operational_points"][0]["id"] = "West!"
    document["operational_points"][2]["id"] = "west?"
    document["operational_points"][2]["parts"] = [{"track": "out", "position": 50}]
    line = valley(document, from_op="West!", to_op="east")
    assert [s.id for s in line.stopping_points] == ["west", "middle", "west-2", "east"]
