"""The precision-stop marker reader: each marker found where the front passes it, within
centimetres, once per pass and lap; markers lost to a fault; the BTM's draws untouched."""

from __future__ import annotations

import math

import numpy as np
import pytest

from onboard.plant.marker_reader import (
    MARKER_LOCATION_BOUND_M,
    StopMarkerReader,
    StopMarkerReaderFaults,
)
from onboard.plant.readings import MarkerDetection
from onboard.plant.sensors import TimeWindow
from trackdb import TrackMap, load_seed_line

DT_S = 0.01
RING = TrackMap(load_seed_line("bologna-ring"))
"""Markers 30 m before the north, east and south stops: 520, 1945 and 3370 m of 5700 m."""


def _drive(
    reader: StopMarkerReader, start_m: float, end_m: float, speed_mps: float
) -> list[MarkerDetection]:
    ticks = math.ceil((end_m - start_m) / (speed_mps * DT_S))
    detections: list[MarkerDetection] = []
    for tick in range(ticks + 1):
        detections += reader.step(tick * DT_S, start_m + speed_mps * tick * DT_S)
    return detections


def test_the_ring_has_a_marker_before_each_stop() -> None:
    stops = {point.id: point.position_m for point in RING.line.stopping_points}
    markers = {marker.id: marker.position_m for marker in RING.line.stop_markers}
    assert markers == {f"{stop}-marker": position - 30.0 for stop, position in stops.items()}


def test_markers_are_found_within_centimetres_each_lap() -> None:
    reader = StopMarkerReader(RING, rng=np.random.default_rng(5))
    speed_mps, start_m = 6.0, 500.0
    detections = _drive(reader, start_m, start_m + RING.length_m + 100.0, speed_mps)
    ids = [d.marker.id for d in detections]
    assert ids == ["north-marker", "east-marker", "south-marker", "north-marker"]
    for detection in detections:
        front_m = RING.normalise(start_m + speed_mps * detection.time_s)
        assert abs(front_m - detection.marker.position_m) <= MARKER_LOCATION_BOUND_M + 1e-9
    assert reader.read == 4
    assert MARKER_LOCATION_BOUND_M <= 0.1


def test_exact_readings_are_interpolated_within_the_tick() -> None:
    reader = StopMarkerReader(RING, rng=np.random.default_rng(0), location_sigma_m=0.0)
    detections = _drive(reader, 510.004, 530.0, 4.0)
    assert [d.marker.id for d in detections] == ["north-marker"]
    assert detections[0].time_s == pytest.approx(9.996 / 4.0, abs=1e-9)


def test_rolling_back_over_a_marker_does_not_read_it_twice() -> None:
    reader = StopMarkerReader(RING, rng=np.random.default_rng(1))
    path = [515.0, 521.0, 518.0, 522.0, 525.0]
    detections = [d for k, x in enumerate(path) for d in reader.step(k * 1.0, x)]
    assert [d.marker.id for d in detections] == ["north-marker"]


def test_lost_readings_are_counted_not_reported() -> None:
    by_id = StopMarkerReader(
        RING,
        rng=np.random.default_rng(2),
        faults=StopMarkerReaderFaults(missed_marker_ids=frozenset({"east-marker"})),
    )
    assert [d.marker.id for d in _drive(by_id, 500.0, 3400.0, 10.0)] == [
        "north-marker",
        "south-marker",
    ]
    assert (by_id.read, by_id.missed) == (2, 1)
    in_window = StopMarkerReader(
        RING,
        rng=np.random.default_rng(2),
        faults=StopMarkerReaderFaults(missed_windows=(TimeWindow(0.0, 10.0),)),
    )
    assert [d.marker.id for d in _drive(in_window, 500.0, 1960.0, 10.0)] == ["east-marker"]
