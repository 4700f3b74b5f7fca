"""The line document: JSON round trips and the committed JSON Schema."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from hypothesis import HealthCheck, given, settings

import trackdb
from tests.trackdb.layouts import small_ring, tiny_line
from tests.trackdb.strategies import lines
from trackdb import (
    SEED_LINES,
    Line,
    LineValidationError,
    line_json_schema,
    load_seed_line,
    parse_line,
)

SCHEMA_FILE = Path(trackdb.__file__).resolve().parent / "line.schema.json"
REGENERATE = "regenerate it with `ato trackdb schema > trackdb/line.schema.json`"


@pytest.fixture(scope="module")
def committed_schema() -> dict[str, Any]:
    schema: dict[str, Any] = json.loads(SCHEMA_FILE.read_text(encoding="utf-8"))
    return schema


def test_committed_json_schema_matches_the_models() -> None:
    committed = SCHEMA_FILE.read_text(encoding="utf-8")
    assert committed == line_json_schema(), (
        f"{SCHEMA_FILE.name} differs from the models: {REGENERATE}"
    )


def test_json_schema_is_stable_text() -> None:
    text = line_json_schema()
    assert text.endswith("}\n")
    assert json.dumps(json.loads(text), indent=2, sort_keys=True, ensure_ascii=False) + "\n" == text


@pytest.mark.parametrize("line_id", sorted(SEED_LINES))
def test_seed_lines_are_valid_under_the_json_schema(
    line_id: str, committed_schema: dict[str, Any]
) -> None:
    document = json.loads(load_seed_line(line_id).model_dump_json(round_trip=True))
    jsonschema.Draft202012Validator(committed_schema).validate(document)


def test_the_json_schema_rejects_an_unknown_field(committed_schema: dict[str, Any]) -> None:
    document = tiny_line().model_dump(mode="json") | {"colour": "red"}
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.Draft202012Validator(committed_schema).validate(document)
    with pytest.raises(LineValidationError):
        parse_line(document)


@pytest.mark.parametrize("build", [tiny_line, small_ring])
def test_layouts_round_trip(build: Any) -> None:
    line: Line = build()
    assert parse_line(line.model_dump_json(round_trip=True)) == line


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(line=lines())
def test_json_round_trip_gives_an_equal_line(line: Line) -> None:
    text = line.model_dump_json(round_trip=True)
    from_text = parse_line(text)
    from_mapping = parse_line(json.loads(text))
    assert from_text == line
    assert from_mapping == line
    assert from_text.version() == line.version()
    assert from_text.model_dump_json(round_trip=True) == text


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(line=lines())
def test_drawn_lines_are_valid_under_the_json_schema(line: Line) -> None:
    schema = json.loads(line_json_schema())
    jsonschema.Draft202012Validator(schema).validate(json.loads(line.model_dump_json()))
