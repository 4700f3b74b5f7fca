"""RailJSON import errors: each names the place in the document (a JSON path) and the reason."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import pytest

from tests.trackdb.railjson_builder import junction_valley
from trackdb import RailJsonError, TrackDataError
from trackdb.railjson import line_from_railjson

Document = dict[str, Any]


def track_index(document: Document, track_id: str) -> int:
    return [t["id"] for t in document["track_sections"]].index(track_id)


def refused(change: Callable[[Document], object], **options: Any) -> RailJsonError:
    document = junction_valley().build()
    change(document)
    options = {"from_op": "westbrook", "to_op": "eastfield", "line_id": "jv"} | options
    with pytest.raises(RailJsonError) as caught:
        line_from_railjson(json.dumps(document), **options)
    error = caught.value
    assert isinstance(error, TrackDataError)
    assert isinstance(error, ValueError)
    assert str(error) == f"{error.json_path}: {error.reason}"
    return error


def _set(path: list[Any], value: Any) -> Callable[[Document], None]:
    def change(document: Document) -> None:
        node = document
        for key in path[:-1]:
            node = node[key] if not callable(key) else key(node)
        node[path[-1]] = value

    return change


def _track(track_id: str) -> Callable[[Document], Any]:
    return lambda document: document["track_sections"][track_index(document, track_id)]


CASES = {
    "wrong type": (
        _set(["track_sections", 3, "slopes"], "steep"),
        "$.track_sections[3].slopes",
        "Input should be a valid list",
    ),
    "negative offset": (
        _set(["detectors", 2, "position"], -1.0),
        "$.detectors[2].position",
        "Input should be greater than or equal to 0",
    ),
    "not finite": (
        _set(["track_sections", 0, "length"], float("inf")),
        "$.track_sections[0].length",
        "Input should be a finite number",
    ),
    "missing": (
        lambda d: d.pop("track_sections"),
        "$.track_sections",
        "Field required",
    ),
    "no version": (
        lambda d: d.pop("version"),
        "$.version",
        "unsupported RailJSON version None: this import reads versions 3.x",
    ),
    "inverted slope": (
        _set([_track("main-02"), "slopes", 0, "begin"], 400.0),
        "$.track_sections[{main-02}].slopes[0]",
        "empty or inverted range: begin 400.0 m, end 300.0 m",
    ),
    "overlapping curves": (
        lambda d: _track("main-08")(d)["curves"].append({"radius": 900, "begin": 800, "end": 1000}),
        "$.track_sections[{main-08}].curves[2]",
        "range 800.0..1000.0 m overlaps another that ends at 900.0 m",
    ),
    "tight curve": (
        _set([_track("main-02"), "curves", 0, "radius"], 30.0),
        "$.track_sections[{main-02}].curves[0].radius",
        "radius 30.0 m below the 50 m a line may have",
    ),
    "speed range beyond": (
        _set(["speed_sections", 0, "track_ranges", 0, "end"], 5000.0),
        "$.speed_sections[0].track_ranges[0]",
        "range 0.0..5000.0 m beyond the track section's length 1500.0 m",
    ),
    "speed unknown track": (
        _set(["speed_sections", 0, "track_ranges", 0, "track"], "nowhere"),
        "$.speed_sections[0].track_ranges[0].track",
        "no track section 'nowhere'",
    ),
    "unknown switch type": (
        _set(["switches", 0, "switch_type"], "turntable"),
        "$.switches[0].switch_type",
        "unknown switch type 'turntable' (known: link, point_switch, crossing, "
        "single_slip_switch, double_slip_switch)",
    ),
    "missing port": (
        lambda d: d["switches"][0]["ports"].pop("B2"),
        "$.switches[0].ports",
        "no port 'B2', which group 'A_B2' of switch type 'point_switch' connects",
    ),
    "port on unknown track": (
        _set(["switches", 0, "ports", "A", "track"], "nowhere"),
        "$.switches[0].ports.A.track",
        "no track section 'nowhere'",
    ),
    "duplicate track": (
        _set(["track_sections", 5, "id"], "main-01"),
        "$.track_sections[5].id",
        "duplicate track section 'main-01'",
    ),
    "part beyond the track": (
        _set(["operational_points", 0, "parts", 0, "position"], 901.0),
        "$.operational_points[0].parts[0].position",
        "901.0 m beyond the length 900.0 m of track section 'main-01'",
    ),
    "no part": (
        _set(["operational_points", 3, "parts"], []),
        "$.operational_points[3].parts",
        "operational point 'eastfield' has no part",
    ),
    "bad coordinates": (
        _set([_track("main-03"), "geo", "coordinates", 4], [7.4, 95.0]),
        "$.track_sections[{main-03}].geo.coordinates[4]",
        "(7.4, 95.0) is not a WGS 84 longitude and latitude",
    ),
    "speed too high": (
        _set(["speed_sections", 0, "speed_limit"], 200.0),
        "$.speed_sections[0].speed_limit",
        "200.0 m/s above the 150 m/s a line allows",
    ),
}


@pytest.mark.parametrize("case", CASES)
def test_errors_name_the_place_and_the_reason(case: str) -> None:
    change, json_path, reason = CASES[case]
    error = refused(change)
    document = junction_valley().build()
    for track_id in ("main-02", "main-03", "main-08"):
        json_path = json_path.replace(f"{{{track_id}}}", str(track_index(document, track_id)))
    assert (error.json_path, error.reason) == (json_path, reason)


def test_an_unknown_via_is_named() -> None:
    error = refused(lambda _: None, via=["millbridge", "atlantis"])
    assert error.json_path == "$.operational_points"
    assert error.reason == "no operational point 'atlantis' (given with --via)"


def test_via_out_of_order_has_no_path() -> None:
    error = refused(lambda _: None, via=["valley-junction", "millbridge"])
    assert error.json_path == "$.operational_points[3]"
    assert error.reason.startswith(
        "no path from 'westbrook' via 'valley-junction' via 'millbridge' to 'eastfield'"
    )


@pytest.mark.parametrize(
    "content", ["", "{", "\ufeff{}", '{"version": "3.5.0", "track_sections": 3']
)
def test_what_is_not_json_is_said_so(content: str) -> None:
    with pytest.raises(RailJsonError) as caught:
        line_from_railjson(content, from_op="a", to_op="b", line_id="x")
    assert caught.value.json_path == "$"
    assert caught.value.reason.startswith("not JSON: ")


def test_an_origin_that_is_the_destination_has_no_line() -> None:
    error = refused(lambda _: None, to_op="westbrook")
    assert (error.json_path, error.reason) == (
        "$.operational_points[0]",
        "the path from 'westbrook' to 'westbrook' has no length",
    )
