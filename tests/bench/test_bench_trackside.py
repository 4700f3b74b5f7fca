"""``ato bench trackside`` keeps working: a small fleet, a short load (figures not asserted)."""

from __future__ import annotations

import math

import pytest

from deploy.bench.trackside_bench import STATUS_PERIOD_S, FleetSchedule, run_bench

pytestmark = pytest.mark.scenario


def test_a_small_bench_measures_rest_and_live_latency() -> None:
    figures = run_bench(vehicles=5, seconds=2.0, rate_hz=20.0, sockets=2, warmup_s=1.0)
    assert figures.requests >= 20
    assert figures.rest_errors == 0  # every request, commands included, was answered
    assert figures.frames > 0
    for values in (figures.rest_ms, figures.live_ms):
        assert math.isfinite(values["p99"])
        assert 0.0 < values["p50"] <= values["p99"]


def test_the_simulated_fleet_reports_at_random_phases_once_a_period() -> None:
    """Each vehicle reports once a period, at its own offset, numbered on from 0; the offsets
    are seeded (the same fleet each run) and not evenly spaced."""
    schedule = FleetSchedule(50)
    first = list(schedule.due(STATUS_PERIOD_S - 1e-9))
    assert sorted(index for index, _ in first) == list(range(50))
    assert {seq for _, seq in first} == {0}
    assert list(schedule.due(STATUS_PERIOD_S - 1e-9)) == []  # nothing taken twice
    second = list(schedule.due(2 * STATUS_PERIOD_S - 1e-9))
    assert [index for index, _ in second] == [index for index, _ in first]  # same phases
    assert {seq for _, seq in second} == {1}
    assert [index for index, _ in FleetSchedule(50).due(1.0)][:50] == [i for i, _ in first]
    other = [index for index, _ in FleetSchedule(50, seed=1).due(STATUS_PERIOD_S)]
    assert other != [index for index, _ in first]
    assert [index for index, _ in first] != list(range(50))


def test_the_simulated_fleet_s_reports_fall_due_over_the_period() -> None:
    """A thousand vehicles' reports spread over the period: every tenth of it holds some, none
    holds a third of them."""
    schedule = FleetSchedule(1000)
    counts = []
    for step in range(1, 11):
        counts.append(len(list(schedule.due(step * STATUS_PERIOD_S / 10))))
    assert sum(counts) == 1000
    assert min(counts) > 0
    assert max(counts) < 333
