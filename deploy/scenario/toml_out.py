"""Writing a scenario as a TOML file, in the library's layout (no third-party writer).

Scalars first, then each table (``[vehicle]``, ``[journey]``), then each array of tables
(``[[journey.timing_points]]``, ``[[actions]]``, ``[[faults]]``); keys at their default are left
out. :func:`scenario_toml` checks that the text reads back as the same scenario.
"""

from __future__ import annotations

import json
import math
from typing import Any

from deploy.scenario.loader import parse_scenario
from deploy.scenario.schema import ScenarioSpec

__all__ = ["scenario_toml"]


def _scalar(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list):
        return "[" + ", ".join(_scalar(item) for item in value) + "]"
    raise TypeError(f"no TOML for {value!r}")


def _is_tables(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _table(name: str, data: dict[str, Any], lines: list[str], *, array: bool) -> None:
    lines.append("")
    lines.append(f"[[{name}]]" if array else f"[{name}]")
    nested = []
    # The discriminating key first, as the library writes it.
    first = [key for key in ("kind", "do", "id") if key in data]
    for key, value in ({k: data[k] for k in first} | data).items():
        if isinstance(value, dict) or _is_tables(value):
            nested.append((key, value))
        elif value is not None and value != []:
            lines.append(f"{key} = {_scalar(value)}")
    for key, value in nested:
        _emit_nested(f"{name}.{key}", value, lines)


def _emit_nested(name: str, value: Any, lines: list[str]) -> None:
    if isinstance(value, dict):
        _table(name, value, lines, array=False)
    else:
        for item in value:
            _table(name, item, lines, array=True)


def scenario_toml(spec: ScenarioSpec, *, comment: str = "") -> str:
    """The scenario file of ``spec``, ``comment`` as its opening ``#`` lines.

    Raises
    ------
    ValueError
        The text does not read back as ``spec`` (a bug here, not in the scenario).
    """
    data = spec.model_dump(mode="json", exclude_defaults=True)
    if spec.invariants is not None:  # the thresholds in full: the file says what it judges
        data["invariants"] = spec.invariants.model_dump(mode="json")
    lines = [f"# {line}".rstrip() for line in comment.splitlines()]
    later = []
    for key, value in data.items():
        if isinstance(value, dict) or _is_tables(value):
            later.append((key, value))
        elif value is not None and value not in ((), []):
            lines.append(f"{key} = {_scalar(value)}")
    for key, value in later:
        _emit_nested(key, value, lines)
    text = "\n".join(lines).lstrip("\n") + "\n"
    if parse_scenario(text, path=f"<{spec.name}>") != spec:
        raise ValueError(f"{spec.name}: the TOML does not read back as the scenario")
    return text
