"""The whole-stack fault scenarios of the library: each run by `ato run`'s runner in lockstep,
each meeting its expectations (safe outcomes: no overspeed, EoA and obstacle never reached)."""

from __future__ import annotations

import pytest

from deploy.scenario import load_scenario
from deploy.scenario.campaign import FAULT_SCENARIOS
from deploy.scenario.runner import RunOptions, run_scenario

pytestmark = pytest.mark.e2e


@pytest.mark.parametrize("name", FAULT_SCENARIOS)
def test_fault_scenario_meets_its_expectations(name: str) -> None:
    kpis = run_scenario(load_scenario(name), RunOptions(fast=True)).kpis
    failed = [item for item in kpis.expectations if not item.ok]
    assert not failed, failed
    assert kpis.max_overspeed_kmh <= 0.0
    if kpis.min_eoa_margin_m is not None:
        assert kpis.min_eoa_margin_m >= 0.0


def test_the_simulated_operator_engages_again_after_a_fallback_stop() -> None:
    """`operator.reengage` in place of the library's second `engage` action: the lost session's
    fallback stop is followed by a new engagement, and the journey is driven to its end."""
    spec = load_scenario("zenoh-link-loss")
    engages = [a for a in spec.actions if a.do == "engage"]
    assert len(engages) == 2
    spec = spec.model_copy(
        update={
            "actions": tuple(a for a in spec.actions if a is not engages[1]),
            "operator": spec.operator.model_copy(update={"reengage": True}),
        }
    )
    kpis = run_scenario(spec, RunOptions(fast=True)).kpis
    done = [a for a in kpis.actions or [] if a.action == "engage" and a.accepted]
    assert len(done) >= 2
    failed = [item for item in kpis.expectations if not item.ok]
    assert not failed, failed
