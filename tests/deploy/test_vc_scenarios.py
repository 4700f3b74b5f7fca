"""The `vc-*` scenario files: one per Vital Control catalogue scenario, each ending in its
expected outcome class with its intervention times in the KPIs."""

from __future__ import annotations

import pytest

from deploy.bench.vc_catalogue import CATALOGUE
from deploy.scenario import load_scenario, scenario_names
from deploy.scenario.runner import RunOptions, run_scenario

BRAKING = {"eb_safe_recovery", "eb_then_decay"}


def test_every_catalogue_scenario_has_its_file() -> None:
    names = set(scenario_names())
    assert {f"vc-{item.key}" for item in CATALOGUE} <= names


@pytest.mark.parametrize("item", CATALOGUE, ids=lambda item: item.key)
def test_vc_scenario_ends_in_its_expected_class(item: object) -> None:
    key, expected = item.key, item.expected.value  # type: ignore[attr-defined]
    kpis = run_scenario(load_scenario(f"vc-{key}"), RunOptions(fast=True)).kpis
    assert kpis.passed, kpis.expectations
    assert kpis.vc_outcome == expected == kpis.vc_expected_outcome
    assert kpis.system_decay == (expected in {"eb_then_decay", "decay_at_standstill"})
    if expected in BRAKING:
        (intervention,) = kpis.vc_interventions[:1]
        command_ms, full_ms = intervention.hazard_to_eb_command_ms, intervention.total_to_full_eb_ms
        assert command_ms is not None
        assert full_ms is not None
        assert 0.0 <= command_ms <= full_ms <= 1000.0
