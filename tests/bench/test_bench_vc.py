"""``ato bench vc`` runs the VC in lockstep and in real time and prints its tables (timings
printed, not tested)."""

from __future__ import annotations

import pytest

from deploy.bench.vc_bench import bench_vc


def test_bench_vc_times_lockstep_runs_and_both_real_time_waits(
    capsys: pytest.CaptureFixture[str],
) -> None:
    results = bench_vc(seconds=0.5, execution_runs=1000, spins_us=(0.0, 500.0))
    assert set(results) == {
        "lockstep",
        "lockstep, event-driven",
        "real time, spin 0 µs",
        "real time, spin 500 µs",
    }
    lockstep, event_driven = results["lockstep"], results["lockstep, event-driven"]
    assert lockstep["vc.B"].runs == lockstep["vc.C"].runs == 1001
    # Event-driven, B and C are one task that is not released while they are quiet.
    assert "vc.B" not in event_driven
    assert 0 < event_driven["vc.tick"].runs < 1001
    assert lockstep["vc.A"].runs == event_driven["vc.A"].runs == 51
    for timings in results.values():
        first = timings["vc.B"] if "vc.B" in timings else timings["vc.tick"]
        assert all(sample > 0 for sample in first.execution_ns)
    real_time = results["real time, spin 500 µs"]
    assert real_time["vc.B"].runs == 251
    assert real_time["vc.A"].runs == 13
    out = capsys.readouterr().out
    assert "execution time in lockstep" in out
    assert "event-driven" in out
    assert "not released at all" in out
    assert "polling the last 500 µs" in out
    for column in ("exec median", "exec p99", "late p99", "misses"):
        assert column in out
