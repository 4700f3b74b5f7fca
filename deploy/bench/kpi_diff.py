"""Two runs' ``kpis.json`` compared, apart from what measures the machine (issue 24).

A lockstep run is deterministic: the same scenario and seed give the same KPIs, bit for bit
(ARCHITECTURE.md, "Time"). A change meant only to make the stack faster must therefore leave
``kpis.json`` identical, apart from the fields measured in wall time, listed once in
:data:`WALL_CLOCK_FIELDS`. :func:`kpi_differences` compares the two documents as JSON (not
through today's model: the ref may write fields the tree no longer knows, or the reverse) and
returns every difference, down to the leaf, with its path (``stops[2].arrival_error_s``); a
value one side lacks is :data:`ABSENT`.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

__all__ = [
    "ABSENT",
    "WALL_CLOCK_FIELDS",
    "KpiDifference",
    "grouped_differences",
    "kpi_differences",
    "shown",
]

WALL_CLOCK_FIELDS: Final = ("wall_time_s", "real_time_factor", "nmpc_ms", "wall_time_breakdown")
"""The fields of ``kpis.json`` measured in wall time. They measure the machine and the moment,
not the run, so the comparison leaves them out, and with them any expectation judged on them
(an expectation ``nmpc_ms.p99 <= 5.0``)."""


class _Absent:
    """A value one document lacks."""

    def __repr__(self) -> str:
        return "absent"


ABSENT: Final = _Absent()


@dataclass(frozen=True)
class KpiDifference:
    """One leaf where the two documents differ."""

    path: str
    """Where: keys joined by dots, list items by index (``stops[2].arrival_error_s``)."""
    tree: Any
    """The tree's value (JSON), or :data:`ABSENT`."""
    ref: Any
    """The ref's value (JSON), or :data:`ABSENT`."""


def _judged_on_wall_clock(expectation: Any) -> bool:
    name = expectation.get("name", "") if isinstance(expectation, dict) else ""
    words = name.split()
    return bool(words) and words[0].split(".")[0].split("[")[0] in WALL_CLOCK_FIELDS


def _run_figures(kpis: dict[str, Any]) -> dict[str, Any]:
    """``kpis`` without its wall-clock fields and the expectations judged on them."""
    kept = {key: value for key, value in kpis.items() if key not in WALL_CLOCK_FIELDS}
    if isinstance(kept.get("expectations"), list):
        kept["expectations"] = [e for e in kept["expectations"] if not _judged_on_wall_clock(e)]
    return kept


def _same(tree: Any, ref: Any) -> bool:
    # JSON's true is not 1, although Python's True == 1.
    return isinstance(tree, bool) == isinstance(ref, bool) and tree == ref


def _compare(path: str, tree: Any, ref: Any, found: list[KpiDifference]) -> None:
    if isinstance(tree, dict) and isinstance(ref, dict):
        keys = [*tree, *(key for key in ref if key not in tree)]
        for key in keys:
            inner = f"{path}.{key}" if path else str(key)
            _compare(inner, tree.get(key, ABSENT), ref.get(key, ABSENT), found)
    elif isinstance(tree, list) and isinstance(ref, list):
        for index in range(max(len(tree), len(ref))):
            _compare(
                f"{path}[{index}]",
                tree[index] if index < len(tree) else ABSENT,
                ref[index] if index < len(ref) else ABSENT,
                found,
            )
    elif not _same(tree, ref):
        found.append(KpiDifference(path, tree, ref))


def kpi_differences(tree: dict[str, Any], ref: dict[str, Any]) -> list[KpiDifference]:
    """Every difference between two ``kpis.json`` documents, wall-clock fields left out, in
    the order of the tree's document (keys only the ref has after)."""
    found: list[KpiDifference] = []
    _compare("", _run_figures(tree), _run_figures(ref), found)
    return found


def grouped_differences(
    pairs: Sequence[tuple[str, Sequence[KpiDifference]]],
) -> list[tuple[KpiDifference, list[str]]]:
    """The differences of several compared pairs (each named, ``run 2``), each distinct one
    once with the names of the pairs it was found in, in the order first found."""
    groups: dict[str, tuple[KpiDifference, list[str]]] = {}
    for name, differences in pairs:
        for difference in differences:
            key = json.dumps([difference.path, shown(difference.tree), shown(difference.ref)])
            groups.setdefault(key, (difference, []))[1].append(name)
    return list(groups.values())


def shown(value: Any, limit: int | None = None) -> str:
    """A value as JSON text (:data:`ABSENT` as ``absent``), cut to ``limit`` characters."""
    text = "absent" if value is ABSENT else json.dumps(value, ensure_ascii=False)
    if limit is not None and len(text) > limit:
        return text[: limit - 1] + "…"
    return text
