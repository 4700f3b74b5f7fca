"""The layout's rules: dependency direction (ARCHITECTURE.md) and complete ``__all__`` lists."""

from __future__ import annotations

import ast
import importlib
import pkgutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("protocol", "trackdb", "onboard", "trackside", "deploy")

ALLOWED: dict[str, set[str]] = {
    "protocol": {"protocol"},
    "trackdb": {"protocol", "trackdb"},
    "onboard": {"protocol", "trackdb", "onboard"},
    "trackside": {"protocol", "trackdb", "trackside"},
    "deploy": set(PACKAGES),
}


def _imported_top_levels(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", PACKAGES)
def test_dependencies_point_one_way(package: str) -> None:
    offenders = []
    for path in sorted((ROOT / package).rglob("*.py")):
        wrong = (_imported_top_levels(path) & set(PACKAGES)) - ALLOWED[package]
        if wrong:
            offenders.append(f"{path.relative_to(ROOT)} imports {sorted(wrong)}")
    assert offenders == []


def test_the_rule_catches_a_cross_import(tmp_path: Path) -> None:
    sample = tmp_path / "x.py"
    sample.write_text("from trackside.main import create_app\nimport onboard.node\n")
    assert _imported_top_levels(sample) >= {"trackside", "onboard"}


def _modules(package: str) -> list[str]:
    module = importlib.import_module(package)
    names = [package]
    for info in pkgutil.walk_packages(module.__path__, prefix=f"{package}."):
        if ".migrations" not in info.name and not info.name.endswith("__main__"):
            names.append(info.name)
    return names


@pytest.mark.parametrize("name", [n for p in ("protocol", "trackdb") for n in _modules(p)])
def test_all_lists_exist(name: str) -> None:
    module = importlib.import_module(name)
    exported = getattr(module, "__all__", None)
    assert exported is not None, f"{name} has no __all__"
    missing = [item for item in exported if not hasattr(module, item)]
    assert missing == []


@pytest.mark.parametrize("package", ["protocol", "trackdb"])
def test_package_all_reexports_public_names_of_private_modules(package: str) -> None:
    top = importlib.import_module(package)
    for name in _modules(package):
        if name.rsplit(".", 1)[-1].startswith("_"):
            module = importlib.import_module(name)
            assert set(module.__all__) <= set(top.__all__), name
