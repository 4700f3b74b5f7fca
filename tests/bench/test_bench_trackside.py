"""``ato bench trackside`` keeps working: a small fleet, a short load (figures not asserted)."""

from __future__ import annotations

import math

import pytest

from deploy.bench.trackside_bench import run_bench

pytestmark = pytest.mark.scenario


def test_a_small_bench_measures_rest_and_live_latency() -> None:
    figures = run_bench(vehicles=5, seconds=2.0, rate_hz=20.0, sockets=2, warmup_s=1.0)
    assert figures.requests >= 20
    assert figures.rest_errors == 0  # every request, commands included, was answered
    assert figures.frames > 0
    for values in (figures.rest_ms, figures.live_ms):
        assert math.isfinite(values["p99"])
        assert 0.0 < values["p50"] <= values["p99"]
