"""``ato bench vc`` runs the VC in real time and prints its table (timings printed, not tested)."""

from __future__ import annotations

import pytest

from deploy.bench_vc import bench_vc


def test_bench_vc_runs_a_second_in_real_time(capsys: pytest.CaptureFixture[str]) -> None:
    timings = bench_vc(seconds=1.0)
    assert timings["vc.B"].runs == timings["vc.C"].runs == 501
    assert timings["vc.A"].runs == 26
    assert all(sample > 0 for sample in timings["vc.B"].execution_ns)
    out = capsys.readouterr().out
    assert "Vital Control in real time" in out
    for column in ("exec median", "exec p99", "late p99", "misses"):
        assert column in out
