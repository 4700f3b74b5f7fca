"""The layout's rules: dependency direction (ARCHITECTURE.md) and complete ``__all__`` lists."""

from __future__ import annotations

import ast
import importlib
import math
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


# One home for the physical constants (docs/decisions.md, "One home for the vehicle's data and
# the physical constants"): protocol.units holds GRAVITY_MPS2 and MPS_PER_KMH; onboard imports.
CONVERSION_NAMES = frozenset(
    {"GRAVITY", "GRAVITY_MPS2", "G_MPS2", "KMH", "KMH_PER_MPS", "MPS_PER_KMH", "MPS_TO_KMH",
     "KMH_TO_MPS"}
)  # fmt: skip
CONSTANT_VALUES = (9.81, 9.80665, 3.6, 1.0 / 3.6)


def _literal_value(node: ast.expr) -> float | None:
    """The number a literal or a literal quotient (``1.0 / 3.6``) stands for, else None."""
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
        return float(node.value)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
        left, right = _literal_value(node.left), _literal_value(node.right)
        if left is not None and right:
            return left / right
    return None


def _own_constants(path: Path) -> list[str]:
    """Module- and class-level names ``path`` binds to gravity or a km/h conversion."""
    tree = ast.parse(path.read_text(), filename=str(path))
    bodies = [tree.body] + [n.body for n in ast.walk(tree) if isinstance(n, ast.ClassDef)]
    found = []
    for body in bodies:
        for statement in body:
            if isinstance(statement, ast.Assign):
                targets, value = statement.targets, statement.value
            elif isinstance(statement, ast.AnnAssign) and statement.value is not None:
                targets, value = [statement.target], statement.value
            else:
                continue
            names = [t.id for t in targets if isinstance(t, ast.Name)]
            number = _literal_value(value)
            is_constant = number is not None and any(
                math.isclose(number, c, rel_tol=1e-12) for c in CONSTANT_VALUES
            )
            found += [n for n in names if n in CONVERSION_NAMES or is_constant]
    return found


def test_onboard_defines_no_gravity_or_kmh_constant_of_its_own() -> None:
    offenders = [
        f"{path.relative_to(ROOT)}: {name}"
        for path in sorted((ROOT / "onboard").rglob("*.py"))
        for name in _own_constants(path)
    ]
    assert offenders == []


def test_the_constant_rule_catches_a_copy(tmp_path: Path) -> None:
    sample = tmp_path / "x.py"
    sample.write_text(
        "GRAVITY_MPS2 = 9.81\nKMH = 1.0 / 3.6\nG = 9.81\n"
        "class C:\n    to_kmh: float = 3.6\n"
        "LIMIT_MPS = 30.0 / 3.6\nfrom protocol.units import MPS_PER_KMH as KMH\n"
    )
    assert _own_constants(sample) == ["GRAVITY_MPS2", "KMH", "G", "to_kmh"]


def test_units_have_one_home() -> None:
    from onboard.etcs import values as etcs_values
    from onboard.plant import point_mass
    from protocol import units
    from trackdb import journey, vehicle

    assert point_mass.GRAVITY_MPS2 is units.GRAVITY_MPS2
    assert etcs_values.KMH is units.MPS_PER_KMH
    assert point_mass.URV_PARAMETERS is vehicle.URV_PARAMETERS
    assert journey.URV_LIMITS.mass_kg == vehicle.URV_PARAMETERS.mass_kg
    assert journey.URV_LIMITS.max_traction_power_w == vehicle.URV_PARAMETERS.max_traction_power_w


# The bench leaves the train (issue 17 item 5): onboard/ holds only what runs in the onboard
# process; whatever drives or scores a part for tests and benches lives in deploy/bench/.
HARNESS_STEMS = frozenset(
    {"bench", "catalogue", "closed_loop", "drive", "harness", "lockstep", "manoeuvres",
     "mission", "plots", "recording", "responder", "runner", "scenarios"}
)  # fmt: skip
HARNESS_IMPORTS = frozenset({"pytest", "hypothesis", "_pytest"})
PRODUCTION_DESPITE_THE_NAME = {
    # The VCU as fitted to the bogie-fidelity vehicle (VcuDrive): the vehicle's drive, stepped
    # by the onboard node every plant tick; it drives actuators, not a test.
    "onboard/vcu/drive.py",
}


def _is_harness_name(stem: str) -> bool:
    return stem in HARNESS_STEMS or any(
        stem.endswith(f"_{word}") or stem.startswith(f"{word}_") for word in HARNESS_STEMS
    )


def test_onboard_holds_no_harness_module() -> None:
    offenders = []
    for path in sorted((ROOT / "onboard").rglob("*.py")):
        relative = path.relative_to(ROOT).as_posix()
        if _is_harness_name(path.stem) and relative not in PRODUCTION_DESPITE_THE_NAME:
            offenders.append(f"{relative}: a harness's name")
        test_imports = _imported_top_levels(path) & HARNESS_IMPORTS
        if test_imports:
            offenders.append(f"{relative} imports {sorted(test_imports)}")
    assert offenders == []


def test_the_harness_rule_catches_one(tmp_path: Path) -> None:
    sample = tmp_path / "x.py"
    sample.write_text("import pytest\nfrom hypothesis import given\n")
    assert _imported_top_levels(sample) & HARNESS_IMPORTS == {"pytest", "hypothesis"}
    assert _is_harness_name("runner") and _is_harness_name("vc_catalogue")
    assert not _is_harness_name("listener") and not _is_harness_name("driving_function")
