"""The typed KPIs (``deploy.scenario.kpi_model.Kpis``): the committed JSON Schema of
``kpis.json``, real runs' files valid under it, the contract's keys and order, strict values."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from pydantic import BaseModel, ValidationError
from typer.testing import CliRunner

import deploy.scenario
from deploy.bench.vc_scenarios import OutcomeClass
from deploy.cli import app
from deploy.scenario import load_scenario
from deploy.scenario.kpi_model import (
    VC_ONLY_FIELDS,
    VC_RUN_FIELDS,
    WHOLE_STACK_FIELDS,
    Kpis,
    VcOutcome,
    kpis_json_schema,
)
from deploy.scenario.kpis import NOT_JUDGED, check_expectations, kpi_value
from deploy.scenario.runner import RunOptions, run_scenario
from deploy.scenario.schema import Expectation
from tests.deploy.kpi_samples import sample_kpis

SCHEMA_FILE = Path(deploy.scenario.__file__).resolve().parent / "kpis.schema.json"
REGENERATE = "regenerate it with `ato scenarios --kpis-schema > deploy/scenario/kpis.schema.json`"
SCENARIOS = Path(deploy.scenario.__file__).resolve().parents[1] / "scenarios"
CONTRACT_FIRST = ("scenario", "passed", "seed", "sim_time_s", "wall_time_s", "real_time_factor")
CONTRACT_KEYS = {
    # CONTRACT.md §4
    "scenario",
    "passed",
    "seed",
    "sim_time_s",
    "wall_time_s",
    "real_time_factor",
    "stops",
    "max_overspeed_kmh",
    "etcs_sb_count",
    "etcs_eb_count",
    "vc_eb_count",
    "system_decay",
    "traction_energy_kwh",
    "regen_energy_kwh",
    "max_jerk_mps3",
    "ad_speed_rms_kmh",
    "rd_speed_rms_kmh",
    "max_switch_du_frac",
    "position_error_m",
    "nmpc_ms",
    "vc_interventions",
    "expectations",
    # CONTRACT.md §6, those the runs write so far
    "etcs_estimate_error_m",
    "odometry_interval_m",
    "nmpc_failures",
    "nmpc_fallback_s",
    "eoa_stops",
}


@pytest.fixture(scope="module")
def committed_schema() -> dict[str, Any]:
    schema: dict[str, Any] = json.loads(SCHEMA_FILE.read_text(encoding="utf-8"))
    return schema


def _validator(schema: dict[str, Any]) -> jsonschema.Draft202012Validator:
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


# -- the committed schema ----------------------------------------------------------------------


def test_committed_json_schema_matches_the_model() -> None:
    committed = SCHEMA_FILE.read_text(encoding="utf-8")
    assert committed == kpis_json_schema(), f"{SCHEMA_FILE.name} differs: {REGENERATE}"


def test_the_cli_prints_the_committed_schema() -> None:
    result = CliRunner().invoke(app, ["scenarios", "--kpis-schema"])
    assert result.exit_code == 0
    assert result.stdout == SCHEMA_FILE.read_text(encoding="utf-8")


def test_a_renamed_kpi_fails_the_schema_and_the_model(committed_schema: dict[str, Any]) -> None:
    document = json.loads(sample_kpis().model_dump_json())
    _validator(committed_schema).validate(document)
    document["max_overspeed_mps"] = document.pop("max_overspeed_kmh")
    with pytest.raises(jsonschema.ValidationError):
        _validator(committed_schema).validate(document)
    with pytest.raises(ValidationError, match="max_overspeed_mps"):
        Kpis.model_validate(document)


def test_every_field_says_its_unit_or_what_it_counts() -> None:
    models: list[type[BaseModel]] = [Kpis, *_nested_models(Kpis)]
    undocumented = [
        f"{model.__name__}.{name}"
        for model in models
        for name, field in model.model_fields.items()
        if not field.description
    ]
    assert undocumented == []
    suffixed = {
        name: field.description or ""
        for name, field in Kpis.model_fields.items()
        if re.search(r"_(m|s|kmh|kwh|mps3|mps|ms|kw)$", name)
    }
    unit_missing = [name for name, text in suffixed.items() if not re.search(r"\[[^\]]+\]", text)]
    assert unit_missing == []


def _nested_models(model: type[Kpis]) -> list[type[BaseModel]]:
    schema = model.model_json_schema()
    return [getattr(deploy.scenario.kpi_model, name) for name in schema["$defs"]]


# -- the contract's keys and order -------------------------------------------------------------


def test_the_contract_keys_are_fields_and_come_first_in_its_order() -> None:
    fields = list(Kpis.model_fields)
    assert set(fields) >= CONTRACT_KEYS
    assert tuple(fields[: len(CONTRACT_FIRST)]) == CONTRACT_FIRST
    written = list(json.loads(sample_kpis().model_dump_json(indent=2)))
    assert tuple(written[: len(CONTRACT_FIRST)]) == CONTRACT_FIRST


def test_each_kind_of_run_writes_its_own_fields() -> None:
    whole_stack = json.loads(sample_kpis().model_dump_json())
    assert not set(VC_ONLY_FIELDS) & set(whole_stack)
    assert "journey_reports" not in whole_stack
    assert set(WHOLE_STACK_FIELDS) <= set(whole_stack)
    assert "min_obstacle_margin_m" in whole_stack  # null, but written: a whole-stack field
    reported = {"stop": "tp1-north", "reason": "timing_infeasible", "at_s": 45.0}
    assert "journey_reports" in sample_kpis(journey_reports=[reported]).model_dump()
    assert set(VC_RUN_FIELDS).isdisjoint(WHOLE_STACK_FIELDS)
    assert set(VC_ONLY_FIELDS) <= set(VC_RUN_FIELDS)


def test_the_vc_outcomes_are_the_catalogue_classes() -> None:
    assert set(VcOutcome.__args__) == {item.value for item in OutcomeClass}  # type: ignore[attr-defined]


# -- strict values -----------------------------------------------------------------------------


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_nan_and_infinity_are_refused_at_construction_and_assignment(value: float) -> None:
    with pytest.raises(ValidationError, match="finite"):
        sample_kpis(max_jerk_mps3=value)
    with pytest.raises(ValidationError, match="finite"):
        sample_kpis(position_error_m={"rms": 0.1, "max": value})
    kpis = sample_kpis()
    with pytest.raises(ValidationError, match="finite"):
        kpis.real_time_factor = value
    with pytest.raises(ValidationError, match="finite"):
        kpis.stops[0].stop_error_m = value
    assert math.isfinite(kpis.real_time_factor)


def test_a_written_file_reads_back_to_the_same_model() -> None:
    kpis = sample_kpis(wall_time_breakdown=_breakdown())
    assert Kpis.model_validate_json(kpis.model_dump_json(indent=2)) == kpis


def _breakdown() -> dict[str, Any]:
    task = {"releases": 10, "total_s": 0.5, "mean_us": 50.0, "share": 0.5}
    return {"lockstep_s": 1.0, "tasks": {"control": task}, "executive_and_slices_s": 0.5}


# -- expectations on the model -----------------------------------------------------------------


def test_expectation_paths_name_the_written_keys() -> None:
    kpis = sample_kpis()
    assert kpi_value(kpis, "stops.stop_error_m") == [0.1]
    assert kpi_value(kpis, "stops.count") == 1
    assert kpi_value(kpis, "position_error_m.rms") == 0.2
    for name in NOT_JUDGED:
        with pytest.raises(KeyError, match="no KPI"):
            kpi_value(kpis, name)
    with pytest.raises(KeyError, match="no KPI"):
        kpi_value(kpis, "vc_outcome")  # not a whole-stack run's
    expect = [
        Expectation(kpi="stops.stop_error_m", op="abs<=", value=0.5),
        Expectation(kpi="nmpc_ms.p99", op="<", value=1.0),
        Expectation(kpi="no_such_kpi", op="==", value=0.0),
    ]
    results = check_expectations(kpis, expect)
    assert [(r.ok, r.detail) for r in results] == [
        (True, "found [0.1]"),
        (False, "found 4.0"),
        (False, "no KPI 'no_such_kpi'"),
    ]


# -- real runs' files under the committed schema -----------------------------------------------


def test_a_vc_run_writes_a_kpis_json_valid_under_the_committed_schema(
    tmp_path: Path, committed_schema: dict[str, Any]
) -> None:
    outcome = run_scenario(load_scenario("vc-A"), RunOptions(fast=True, report_dir=tmp_path))
    text = (tmp_path / "kpis.json").read_text(encoding="utf-8")
    document = json.loads(text)
    _validator(committed_schema).validate(document)
    assert list(document) == list(VC_RUN_FIELDS)
    assert Kpis.model_validate_json(text) == outcome.kpis
    assert document["passed"] is True
    assert document["real_time_factor"] > 0.0


@pytest.mark.e2e
def test_a_whole_stack_run_writes_a_kpis_json_valid_under_the_committed_schema(
    tmp_path: Path, committed_schema: dict[str, Any]
) -> None:
    # The field test cut to 30 s: the whole stack runs and fails its stops, which is beside
    # the point here.
    text = (SCENARIOS / "bologna-ring.toml").read_text()
    short = tmp_path / "short-ring.toml"
    short.write_text(re.sub(r"(?m)^duration_s = .*$", "duration_s = 30.0", text, count=1))
    report = tmp_path / "report"
    outcome = run_scenario(load_scenario(str(short)), RunOptions(fast=True, report_dir=report))
    written = (report / "kpis.json").read_text(encoding="utf-8")
    document = json.loads(written)
    _validator(committed_schema).validate(document)
    assert tuple(document)[: len(CONTRACT_FIRST)] == CONTRACT_FIRST
    assert set(document) == set(Kpis.model_fields) - {*VC_ONLY_FIELDS, "journey_reports", "fleet"}
    assert Kpis.model_validate_json(written) == outcome.kpis
    assert document["wall_time_breakdown"]["outside_lockstep_s"] is not None
    assert "control" in document["wall_time_breakdown"]["tasks"]
