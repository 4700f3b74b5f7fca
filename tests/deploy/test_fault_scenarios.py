"""The whole-stack fault scenarios of the library, each run by `ato run`'s runner in lockstep with
its own seed, two at a time over the campaign's worker processes: each meets its expectations,
with safe outcomes (no overspeed, EoA and obstacle never reached)."""

from __future__ import annotations

import pytest

from deploy.scenario import load_scenario
from deploy.scenario.campaign import FAULT_SCENARIOS, Cell, run_campaign

pytestmark = pytest.mark.e2e


@pytest.mark.timeout(1200)
def test_every_fault_scenario_meets_its_expectations() -> None:
    cells = [Cell(name, load_scenario(name).seed) for name in FAULT_SCENARIOS]
    problems: dict[str, object] = {}
    for result in run_campaign(cells, workers=2):
        kpis = result.kpis
        if kpis is None:
            problems[result.cell.label] = result.error
            continue
        failed = [item for item in kpis["expectations"] if not item["ok"]]
        margin = kpis["min_eoa_margin_m"]
        if (
            failed
            or result.unsafe
            or kpis["max_overspeed_kmh"] > 0.0
            or (margin is not None and margin < 0.0)
        ):
            problems[result.cell.label] = {"failed": failed, "unsafe": result.unsafe}
    assert not problems, problems
