"""The TrackMap benchmark's own code keeps working (its timings are printed, not tested)."""

from __future__ import annotations

import pytest

from deploy.bench.trackdb_bench import BENCH_LINES, TARGETS_MEDIAN_US, bench_trackdb, time_calls


def test_time_calls_times_each_call() -> None:
    seen: list[int] = []
    samples_ns = time_calls(seen.append, list(range(50)))
    assert len(samples_ns) == 50
    assert all(sample >= 0 for sample in samples_ns)
    assert seen[-50:] == list(range(50))


def test_bench_trackdb_reports_every_query(capsys: pytest.CaptureFixture[str]) -> None:
    results = bench_trackdb(count=300)
    assert list(results) == list(BENCH_LINES)
    for queries in results.values():
        assert set(TARGETS_MEDIAN_US) <= set(queries)
        for figures in queries.values():
            assert figures["count"] == 300
            assert 0.0 < figures["median_us"] <= figures["p99_us"] <= figures["max_us"]
    # The targets apply on milano-bologna only.
    targets = {q for q, f in results["milano-bologna"].items() if "target_median_us" in f}
    assert targets == set(TARGETS_MEDIAN_US)
    assert not any("target_median_us" in f for f in results["bologna-ring"].values())
    assert "TrackMap queries" in capsys.readouterr().out
