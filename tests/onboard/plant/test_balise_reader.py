"""The balise reader: detections where the front passes each group (plus the reading's error),
interpolated in time, across the ring's origin; missed groups; determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from onboard.plant.balise_reader import (
    LOCATION_BOUND_M,
    LOCATION_SIGMA_M,
    BaliseReader,
    BaliseReaderFaults,
)
from onboard.plant.readings import BaliseDetection
from onboard.plant.sensors import TimeWindow
from trackdb import TrackMap, load_seed_line

DT_S = 0.01
RING = TrackMap(load_seed_line("bologna-ring"))
"""Groups 101–104 at 150, 1800, 2950 and 4650 m of a 5700 m ring."""


def _drive(
    reader: BaliseReader, start_m: float, end_m: float, speed_mps: float
) -> list[BaliseDetection]:
    """Run the front at a steady speed from ``start_m`` to ``end_m``, ticking the reader."""
    ticks = math.ceil((end_m - start_m) / (speed_mps * DT_S))
    detections: list[BaliseDetection] = []
    for tick in range(ticks + 1):
        detections += reader.step(tick * DT_S, start_m + speed_mps * tick * DT_S)
    return detections


def test_exact_readings_are_at_the_group_interpolated_within_the_tick() -> None:
    reader = BaliseReader(RING, rng=np.random.default_rng(0), location_sigma_m=0.0)
    detections = _drive(reader, 140.004, 160.0, 7.0)
    assert [d.group.id for d in detections] == [101]
    # The front reaches 150 m after 9.996 m at 7 m/s, inside the tick ending at 1.43 s.
    assert detections[0].time_s == pytest.approx(9.996 / 7.0, abs=1e-9)
    assert reader.read == 1
    assert reader.missed == 0


def test_two_laps_of_the_ring_read_every_group_each_lap() -> None:
    reader = BaliseReader(RING, rng=np.random.default_rng(3))
    speed_mps, start_m = 50.0, 5600.0
    detections = _drive(reader, start_m, start_m + 2 * RING.length_m, speed_mps)
    assert [d.group.id for d in detections] == [101, 102, 103, 104] * 2
    times = [d.time_s for d in detections]
    assert times == sorted(times)
    # Each group's location unwrapped on the lap the front meets it (the drive starts on lap 0).
    unwrapped = [5850.0, 7500.0, 8650.0, 10350.0, 11550.0, 13200.0, 14350.0, 16050.0]
    for detection, location_m in zip(detections, unwrapped, strict=True):
        front_m = start_m + speed_mps * detection.time_s
        assert abs(front_m - location_m) <= LOCATION_BOUND_M
    # The second lap's readings carry new errors, not the first lap's again.
    errors = [
        start_m + speed_mps * d.time_s - m for d, m in zip(detections, unwrapped, strict=True)
    ]
    assert errors[:4] != pytest.approx(errors[4:], abs=1e-6)


def test_location_errors_have_the_documented_sigma_and_bound() -> None:
    errors = []
    for seed in range(1000):
        reader = BaliseReader(RING, rng=np.random.default_rng(seed))
        speed_mps, start_m = 20.0, 1795.0
        (detection,) = _drive(reader, start_m, 1805.0, speed_mps)
        error_m = start_m + speed_mps * detection.time_s - 1800.0
        assert error_m == pytest.approx(reader.last_errors_m[102], abs=1e-9)
        errors.append(error_m)
    array = np.array(errors)
    # A normal truncated at ±2.5 σ has σ 0.9546 of the untruncated one.
    assert array.std() == pytest.approx(0.9546 * LOCATION_SIGMA_M, rel=0.07)
    assert abs(array.mean()) < 3.0 * LOCATION_SIGMA_M / math.sqrt(array.size)
    assert np.abs(array).max() <= LOCATION_BOUND_M


def test_missed_groups_and_windows_are_not_reported_but_counted() -> None:
    by_id = BaliseReader(
        RING,
        rng=np.random.default_rng(1),
        faults=BaliseReaderFaults(missed_group_ids=frozenset({102})),
    )
    assert [d.group.id for d in _drive(by_id, 0.0, 5000.0, 50.0)] == [101, 103, 104]
    assert (by_id.read, by_id.missed) == (3, 1)
    # Group 103 (2950 m) passes at about 59 s at 50 m/s.
    faults = BaliseReaderFaults(missed_windows=(TimeWindow(55.0, 62.0),))
    in_window = BaliseReader(RING, rng=np.random.default_rng(1), faults=faults)
    assert [d.group.id for d in _drive(in_window, 0.0, 5000.0, 50.0)] == [101, 102, 104]
    assert (in_window.read, in_window.missed) == (3, 1)


def test_same_seed_same_readings_another_seed_others() -> None:
    def times(seed: int) -> list[float]:
        return [
            d.time_s
            for d in _drive(BaliseReader(RING, rng=np.random.default_rng(seed)), 0.0, 5000.0, 30.0)
        ]

    assert times(11) == times(11)
    assert times(11) != times(12)


def test_rolling_back_and_on_again_reads_a_group_once() -> None:
    reader = BaliseReader(RING, rng=np.random.default_rng(2), location_sigma_m=0.0)
    positions = [145.0, 149.0, 151.0, 148.0, 146.0, 149.5, 152.0, 160.0]
    detections = [d for k, m in enumerate(positions) for d in reader.step(k * 1.0, m)]
    assert [d.group.id for d in detections] == [101]
    assert detections[0].time_s == pytest.approx(1.5)


def test_the_first_step_places_the_reader_without_reading_behind_it() -> None:
    at_group = BaliseReader(RING, rng=np.random.default_rng(0), location_sigma_m=0.0)
    assert _drive(at_group, 150.0, 200.0, 10.0) == []
    before = BaliseReader(RING, rng=np.random.default_rng(0), location_sigma_m=0.0)
    assert [d.group.id for d in _drive(before, 149.5, 200.0, 10.0)] == [101]


def test_a_bound_below_sigma_is_refused() -> None:
    with pytest.raises(ValueError, match="location_bound_m"):
        BaliseReader(RING, rng=np.random.default_rng(0), location_sigma_m=2.0)


class _AlwaysLooking(BaliseReader):
    """The reader without its look ahead: every tick asks the track for its window."""

    def _passes(self, front_m: float):
        passes = super()._passes(front_m)
        self._clear_until_m = -math.inf
        return passes


def test_skipping_ticks_with_nothing_in_reach_reads_the_same() -> None:
    """The look ahead (``LOOK_AHEAD_M``) only spares the ticks with no point within reach: over
    two laps of the ring with random speeds, standstills and roll-backs, the same detections,
    errors and counts as a reader that looks at every tick."""
    rng = np.random.default_rng(24)
    readers = [
        cls(RING, rng=np.random.default_rng(5), location_sigma_m=0.4, location_bound_m=1.0)
        for cls in (BaliseReader, _AlwaysLooking)
    ]
    front_m = 5500.0
    found: list[list[BaliseDetection]] = [[], []]
    for tick in range(60_000):
        front_m += float(rng.choice([0.0, -0.02, 0.05, 0.2, 0.4], p=[0.05, 0.05, 0.2, 0.3, 0.4]))
        for reader, detections in zip(readers, found, strict=True):
            detections += reader.step(tick * DT_S, front_m)
    assert front_m > 5500.0 + 2 * RING.length_m
    assert found[0] == found[1]
    assert len(found[0]) >= 8
    assert readers[0].last_errors_m == readers[1].last_errors_m
    assert (readers[0].read, readers[0].missed) == (readers[1].read, readers[1].missed)
