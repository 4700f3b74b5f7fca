"""A generated campaign's kept results: taken back only for the same scenario, seed and code."""

from __future__ import annotations

from pathlib import Path

from deploy.scenario.campaign import Cell, CellResult
from deploy.scenario.run_store import RunStore, code_fingerprint
from tests.deploy.kpi_samples import sample_kpis


def _cell(tmp_path: Path, seed: int = 3) -> Cell:
    scenario = tmp_path / "gen-1-0.toml"
    if not scenario.exists():
        scenario.write_text('name = "gen-1-0"\n')
    return Cell(str(scenario), seed)


def test_a_kept_result_comes_back_as_it_was(tmp_path: Path) -> None:
    store = RunStore(tmp_path / "results", "code-a")
    ran, crashed = sample_kpis(seed=3), "Traceback: boom"
    store.save(CellResult(_cell(tmp_path), ran))
    assert store.load(_cell(tmp_path)) == CellResult(_cell(tmp_path), ran)
    store.save(CellResult(_cell(tmp_path), None, crashed))
    assert store.load(_cell(tmp_path)) == CellResult(_cell(tmp_path), None, crashed)
    assert [p.name for p in (tmp_path / "results").iterdir()] == ["gen-1-0.json"]


def test_another_code_seed_or_scenario_or_a_bad_file_is_run_again(tmp_path: Path) -> None:
    store = RunStore(tmp_path / "results", "code-a")
    store.save(CellResult(_cell(tmp_path), sample_kpis()))
    assert RunStore(tmp_path / "results", "code-b").load(_cell(tmp_path)) is None
    assert store.load(_cell(tmp_path, seed=4)) is None
    Path(_cell(tmp_path).scenario).write_text('name = "gen-1-0"\n# edited\n')
    assert store.load(_cell(tmp_path)) is None
    store.save(CellResult(_cell(tmp_path), sample_kpis()))
    for text in ("{not json", "[]", '{"kpis": null}'):
        (tmp_path / "results" / "gen-1-0.json").write_text(text)
        assert store.load(_cell(tmp_path)) is None


def test_the_code_fingerprint_follows_the_sources(tmp_path: Path) -> None:
    for package in ("protocol", "trackdb", "onboard", "trackside", "deploy"):
        (tmp_path / package).mkdir()
        (tmp_path / package / "__init__.py").write_text("")
    before = code_fingerprint(tmp_path)
    assert code_fingerprint(tmp_path) == before
    (tmp_path / "onboard" / "adf.py").write_text("GAIN = 1\n")
    assert code_fingerprint(tmp_path) != before
    assert len(code_fingerprint()) == 64
