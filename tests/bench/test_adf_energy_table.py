"""The energy-plan table of ``ato bench adf`` (issue 22) on a few legs."""

from __future__ import annotations

import pytest

from deploy.bench.adf_energy_table import (
    BenchLeg,
    LegResult,
    generated_legs,
    leg_result,
    named_legs,
    summary,
)
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.scenario


def test_the_named_legs_cover_what_issue_22_asks_for() -> None:
    legs = named_legs()
    names = [leg.name for leg in legs]
    assert sum(name.startswith("ring lap") for name in names) == 3
    milano = [leg for leg in legs if leg.name.startswith("m-b")]
    assert len(milano) == 3
    assert any(leg.distance_m >= 30_000.0 and leg.cap_mps == 200 * MPS_PER_KMH for leg in milano)
    assert sum(bool(leg.passing) for leg in legs) == 1


def test_generated_legs_are_the_generators_draws_and_repeat() -> None:
    first, again = generated_legs(4), generated_legs(4)
    assert [(leg.name, leg.distance_m, leg.duration_s) for leg in first] == [
        (leg.name, leg.distance_m, leg.duration_s) for leg in again
    ]
    assert len(first) == 4
    assert all(leg.distance_m > 0.0 and leg.duration_s > 0.0 for leg in first)


def test_a_ring_leg_is_measured_against_the_optimum_and_the_lspb() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    leg = BenchLeg("east → south", ring, 1975.0, 1425.0, 230.0, 40 * MPS_PER_KMH)
    result = leg_result(leg)
    assert result.optimum_j is not None
    above = result.above_optimum_pct
    assert above is not None
    assert above <= 1.0
    assert result.below_lspb_pct >= 10.0
    assert not result.fallback
    assert result.slack > 0.05
    figures = summary([result])
    assert figures["fallbacks"] == 0.0
    assert figures["max_above_optimum_pct"] == pytest.approx(above)


def test_the_summary_leaves_out_failed_optima_and_tight_legs() -> None:
    results = [
        LegResult("a", 1000.0, 90.0, 100.0, 89.0, 0.2, False, 0.1),
        LegResult("b", 1000.0, 99.0, 100.0, None, 0.01, True, 0.3),
    ]
    figures = summary(results)
    assert figures["max_above_optimum_pct"] == pytest.approx(100.0 * (90.0 / 89.0 - 1.0))
    assert figures["min_below_lspb_pct"] == pytest.approx(10.0)  # b's slack is under 5 %
    assert figures["fallbacks"] == 1.0
    assert figures["optimum_failures"] == 1.0
    assert figures["plan_max_s"] == pytest.approx(0.3)
