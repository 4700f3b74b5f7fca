"""The scenario catalogue: classes, counts beside the seeds', FSM coverage, timing, determinism."""

from __future__ import annotations

from dataclasses import replace

import pytest

from deploy.bench.vc_catalogue import CATALOGUE, scenario
from deploy.bench.vc_fused_speed import FusedComparison
from deploy.bench.vc_runner import ScenarioResult, count_by_class, format_report, run_scenario
from deploy.bench.vc_scenarios import SEED_HAZARDOUS_COUNTS, SEED_SCENARIO_COUNT, OutcomeClass
from onboard.vc import Fsm, PairEventKind, transition_coverage

pytestmark = pytest.mark.scenario

SEED_LETTERS = {"A", "B", "C", "D", "E", "F", "G", "L", "M", "N"}


def test_the_catalogue_has_the_seeds_size_and_letters() -> None:
    assert len(CATALOGUE) == SEED_SCENARIO_COUNT
    assert len({s.key for s in CATALOGUE}) == len(CATALOGUE)
    assert {s.seed_letter for s in CATALOGUE if s.seed_letter} == SEED_LETTERS
    expected = {c: sum(s.expected is c for s in CATALOGUE) for c in OutcomeClass}
    assert expected == {**SEED_HAZARDOUS_COUNTS, OutcomeClass.NONE: 13}


@pytest.mark.parametrize("key", [s.key for s in CATALOGUE])
def test_each_scenario_gives_its_expected_class(
    catalogue_results: dict[str, ScenarioResult], key: str
) -> None:
    result = catalogue_results[key]
    assert result.outcome is result.expected, result.title


def test_counts_by_class_match_the_seeds(catalogue_results: dict[str, ScenarioResult]) -> None:
    counts = count_by_class(catalogue_results.values())
    assert {c: counts[c] for c in SEED_HAZARDOUS_COUNTS} == SEED_HAZARDOUS_COUNTS
    assert sum(counts[c] for c in SEED_HAZARDOUS_COUNTS) == 23
    assert counts[OutcomeClass.NONE] == SEED_SCENARIO_COUNT - 23


def test_every_transition_of_the_three_fsms_is_taken(
    catalogue_results: dict[str, ScenarioResult],
) -> None:
    coverage = transition_coverage(t for r in catalogue_results.values() for t in r.transitions)
    assert set(coverage) == set(Fsm)
    for item in coverage.values():
        assert item.rows_missing == ()
        assert item.rows_covered == 1.0
        assert item.pairs_missing == ()
        assert item.pairs_covered == 1.0


def test_every_eb_is_full_within_1_s_of_the_hazard(
    catalogue_results: dict[str, ScenarioResult],
) -> None:
    """SUBSET-041's 1 s for the whole chain, with the 450 ms pipe (DOMAIN.md §6, §7.2)."""
    braking = [
        r
        for r in catalogue_results.values()
        if r.outcome in (OutcomeClass.EB_SAFE_RECOVERY, OutcomeClass.EB_THEN_DECAY)
    ]
    assert len(braking) == 15
    for result in braking:
        assert result.hazard_to_full_eb_s is not None
        assert result.hazard_to_eb_command_s is not None
        assert result.hazard_to_full_eb_s <= 1.0, result.key
        assert result.hazard_to_full_eb_s - result.hazard_to_eb_command_s == pytest.approx(0.45)
        assert (result.speed_at_intervention_kmh or 0.0) > 20.0


def test_nothing_brakes_or_decays_in_the_nominal_scenarios(
    catalogue_results: dict[str, ScenarioResult],
) -> None:
    for result in catalogue_results.values():
        if result.expected is OutcomeClass.NONE:
            assert result.eb_command_s is None, result.key
            assert result.decay_s is None, result.key


def test_the_pipe_time_is_a_scenario_parameter() -> None:
    slow = replace(scenario("B"), full_eb_delay_s=0.3)
    result = run_scenario(slow)
    assert result.hazard_to_full_eb_s is not None
    assert result.hazard_to_eb_command_s is not None
    assert result.hazard_to_full_eb_s - result.hazard_to_eb_command_s == pytest.approx(0.3)


def test_a_run_is_deterministic(catalogue_results: dict[str, ScenarioResult]) -> None:
    again = run_scenario(scenario("M-noisy"))
    first = catalogue_results["M-noisy"]
    assert again.events == first.events
    assert again.transitions == first.transitions


def test_the_report_compares_with_the_seeds(catalogue_results: dict[str, ScenarioResult]) -> None:
    report = format_report(list(catalogue_results.values()))
    assert "36 scenarios (seeds: 36), 23 hazardous (seeds: 23)" in report
    assert "eb_then_decay           10   seeds  10" in report
    assert "rows 100% of 6, (row, source) pairs 100% of 10" in report


def test_a_2oo2_pair_ends_every_scenario_like_one_vc(
    catalogue_results: dict[str, ScenarioResult], pair_results: dict[str, ScenarioResult]
) -> None:
    """Both replicas see the same inputs: the pair brakes when they brake, at the same tick,
    and never trips on a disagreement or a watchdog."""
    for key, single in catalogue_results.items():
        paired = pair_results[key]
        assert paired.outcome is single.outcome, key
        assert paired.eb_command_s == single.eb_command_s, key
        assert paired.decay_s == single.decay_s, key
        assert all(e.kind is PairEventKind.REPLICA_EB for e in paired.pair_events), key


def test_the_fused_speed_brings_overspeed_under_500_ms_and_never_later(
    fused_comparison: dict[str, FusedComparison],
) -> None:
    overspeed = fused_comparison["L"]
    assert overspeed.tachometer.hazard_to_full_eb_s is not None
    assert overspeed.tachometer.hazard_to_full_eb_s > 0.5
    totals = overspeed.fused_values("hazard_to_full_eb_s")
    assert len(totals) == len(overspeed.fused)
    assert max(totals) <= 0.5
    assert max(totals) <= overspeed.tachometer.hazard_to_full_eb_s
    assert all(r.outcome is OutcomeClass.EB_SAFE_RECOVERY for r in overspeed.fused)


def test_the_fused_speed_changes_nothing_below_the_limit_or_for_board_faults(
    fused_comparison: dict[str, FusedComparison],
) -> None:
    below = fused_comparison["isolated-28kmh"]
    assert all(r.outcome is OutcomeClass.NONE for r in below.fused)
    for key in ("M", "M-silent", "M-noisy"):
        item = fused_comparison[key]
        assert {r.hazard_to_full_eb_s for r in item.fused} == {
            item.tachometer.hazard_to_full_eb_s
        }, key
