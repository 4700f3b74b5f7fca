"""The code's size rules (STYLE.md, issue 19): no class over 300 lines and no function over 60
in the packages, unless listed below with a one-line reason.

A class or function counts from its ``class``/``def`` line to the end of its body, docstring
included. An entry that no longer exceeds its limit must leave the list.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("protocol", "trackdb", "onboard", "trackside", "deploy")
MAX_CLASS_LINES = 300
MAX_FUNCTION_LINES = 60

EXCEPTIONS: dict[str, str] = {}
"""``path:qualified name`` → why it may be longer than the rule allows."""


def oversized(source: str, path: str) -> dict[str, int]:
    """Every class over :data:`MAX_CLASS_LINES` and function over :data:`MAX_FUNCTION_LINES`
    in ``source``, by ``path:qualified name``, with its length in lines."""
    found: dict[str, int] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
                name = f"{prefix}{child.name}"
                assert child.end_lineno is not None
                lines = child.end_lineno - child.lineno + 1
                limit = MAX_CLASS_LINES if isinstance(child, ast.ClassDef) else MAX_FUNCTION_LINES
                if lines > limit:
                    found[f"{path}:{name}"] = lines
                visit(child, f"{name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(source), "")
    return found


def _all_oversized() -> dict[str, int]:
    found: dict[str, int] = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            found |= oversized(path.read_text(), path.relative_to(ROOT).as_posix())
    return found


def test_no_class_or_function_over_its_limit_without_a_reason() -> None:
    found = _all_oversized()
    unexplained = {name: lines for name, lines in found.items() if name not in EXCEPTIONS}
    assert unexplained == {}
    stale = sorted(set(EXCEPTIONS) - set(found))
    assert stale == [], "no longer over the limit: remove from EXCEPTIONS"
    assert all(reason.strip() for reason in EXCEPTIONS.values())


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("def f():\n" + "    x = 1\n" * 60, {"m.py:f": 61}),
        ("class C:\n    def g(self):\n" + "        y = 2\n" * 60, {"m.py:C.g": 61}),
        ("def f():\n" + "    x = 1\n" * 59, {}),
    ],
)
def test_the_rule_catches_a_long_function(source: str, expected: dict[str, int]) -> None:
    assert oversized(source, "m.py") == expected
