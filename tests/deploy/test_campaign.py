"""`ato campaign`: the matrix, variations, the unsafe classification and the JSON summary."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from deploy.cli import app
from deploy.scenario import campaign, load_scenario
from deploy.scenario.campaign import (
    Cell,
    CellResult,
    apply_setting,
    matrix,
    parse_variation,
    summarise,
)
from tests.deploy.kpi_samples import sample_kpis

pytestmark = pytest.mark.scenario


def test_variations_parse_and_set_a_field_by_its_path() -> None:
    variation = parse_variation("faults.0.at_s=90,110.5")
    assert variation.path == "faults.0.at_s"
    assert variation.values == (90, 110.5)
    spec = apply_setting(load_scenario("ma-shortened"), [("faults.0.at_s", 90)])
    assert spec.faults[0].at_s == 90.0  # type: ignore[union-attr]
    with pytest.raises(ValueError, match="names nothing"):
        apply_setting(load_scenario("vc-A"), [("faults.0.at_s", 90)])
    with pytest.raises(ValueError, match="greater than or equal to 0"):
        apply_setting(load_scenario("ma-shortened"), [("faults.0.at_s", -5)])
    with pytest.raises(ValueError, match="KEY=V1,V2"):
        parse_variation("no-equals-sign")


def test_the_matrix_is_the_product_of_scenarios_seeds_and_variations() -> None:
    cells = matrix(["a", "b"], range(3), [parse_variation("x=1,2")])
    assert len(cells) == 12
    assert cells[0] == Cell("a", 0, (("x", 1),))


def test_unsafe_outcomes_are_told_from_failed_expectations() -> None:
    base = {"passed": False, "max_overspeed_kmh": 1.0, "min_eoa_margin_m": 3.0}
    assert CellResult(Cell("s", 0), sample_kpis(**base)).unsafe == []  # below dV_ebi
    worse = sample_kpis(**base | {"max_overspeed_kmh": 9.0, "min_eoa_margin_m": -0.5})
    unsafe = CellResult(Cell("s", 0), worse)
    assert len(unsafe.unsafe) == 2
    crashed = CellResult(Cell("s", 1), None, "Traceback ...")
    summary = summarise([unsafe, crashed])
    assert summary["unsafe"] == 1
    assert summary["crashed"] == 1
    assert summary["scenarios"]["s"]["kpis"]["max_overspeed_kmh"]["max"] == 9.0
    assert summary["scenarios"]["s"]["kpis"]["position_error_m.rms"]["max"] == 0.2
    assert summary["scenarios"]["s"]["kpis"]["stops.stop_error_m.abs"]["max"] == 0.1
    assert summary["cells"][0]["stops"] == {"stop_error_m": [0.1], "arrival_error_s": [1.0]}


def test_a_campaign_over_worker_processes_writes_its_summary(tmp_path: Path) -> None:
    out = tmp_path / "summary.json"
    result = CliRunner().invoke(
        app, ["campaign", "vc-A", "vc-B", "--seeds", "2", "--workers", "2", "--json", str(out)]
    )
    assert result.exit_code == 0, result.output
    summary = json.loads(out.read_text())
    assert summary["runs"] == 4
    assert summary["passed"] == 4
    assert summary["crashed"] == 0
    assert {cell["seed"] for cell in summary["cells"]} == {0, 1}
    lines = re.findall(
        r"^\[\d/4\] (vc-[AB] seed=[01]): passed \(RTF [\d.]+\)$", result.output, re.MULTILINE
    )
    assert sorted(lines) == ["vc-A seed=0", "vc-A seed=1", "vc-B seed=0", "vc-B seed=1"]


def test_workers_are_replaced_and_the_results_keep_the_cells_order(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Two runs a worker: five cells over two slots need at least three worker processes.
    monkeypatch.setattr(campaign, "RUNS_PER_WORKER", 2)
    cells = [Cell(name, seed) for seed in (0, 1) for name in ("vc-A", "vc-B")] + [Cell("vc-A", 2)]
    seen: list[str] = []
    results = campaign.run_campaign(cells, workers=2, on_result=lambda r: seen.append(r.cell.label))
    assert [r.cell for r in results] == cells
    assert all(r.kpis is not None and r.kpis.passed for r in results)
    assert sorted(seen) == sorted(cell.label for cell in cells)
