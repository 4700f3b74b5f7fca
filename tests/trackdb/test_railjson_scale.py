"""RailJSON import at scale: a 200 km path over hundreds of sections, and the document size limit
(the 50 MB measurement is in docs/trackdb.md; the suite does not churn that much memory)."""

from __future__ import annotations

import time

import pytest

from tests.trackdb.railjson_builder import long_line
from trackdb import RailJsonError, TrackMap
from trackdb.railjson import MAX_DOCUMENT_BYTES, line_from_railjson, read_infra

SECTIONS = 400
SECTION_M = 500.0


def test_a_200_km_path_over_400_sections() -> None:
    document = long_line(SECTIONS, SECTION_M).dumps()
    started = time.perf_counter()
    line = line_from_railjson(document, from_op="start", to_op="end", line_id="long")
    took = time.perf_counter() - started
    assert took < 10.0
    assert line.length_m == pytest.approx(SECTIONS * SECTION_M)
    assert [(s.id, s.position_m) for s in line.stopping_points] == [
        ("start", pytest.approx(50.0)),
        ("end", pytest.approx(SECTIONS * SECTION_M - 50.0)),
    ]
    # Sections alternate forwards and backwards: -1 ‰ and +2 ‰ as walked, every one of them.
    assert len(line.gradient_permille) == SECTIONS
    assert [s.value for s in line.gradient_permille[:4]] == [-1.0, 2.0, -1.0, 2.0]
    assert len(line.balise_groups) == SECTIONS - 1  # one at each detector
    assert line.geodetic[-1].chainage_m == line.length_m
    track = TrackMap(line)
    assert track.speed_limit_mps(150_000.0) == pytest.approx(120 / 3.6)


def test_the_other_way_round_too() -> None:
    document = long_line(SECTIONS, SECTION_M).dumps()
    line = line_from_railjson(document, from_op="end", to_op="start", line_id="long")
    assert line.length_m == pytest.approx(SECTIONS * SECTION_M)
    assert [s.value for s in line.gradient_permille[:2]] == [-2.0, 1.0]


def test_a_document_over_the_limit_is_refused_before_it_is_read() -> None:
    class Huge(bytes):
        """Reports a length over the limit without holding it."""

        def __len__(self) -> int:
            return MAX_DOCUMENT_BYTES + 1

    with pytest.raises(RailJsonError) as caught:
        read_infra(Huge(b"{}"))
    assert caught.value.json_path == "$"
    assert f"over the limit of {MAX_DOCUMENT_BYTES} bytes" in caught.value.reason
