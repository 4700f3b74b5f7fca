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


@pytest.mark.parametrize("name", [n for p in PACKAGES for n in _modules(p)])
def test_all_lists_exist(name: str) -> None:
    module = importlib.import_module(name)
    exported = getattr(module, "__all__", None)
    assert exported is not None, f"{name} has no __all__"
    missing = [item for item in exported if not hasattr(module, item)]
    assert missing == []


@pytest.mark.parametrize("package", PACKAGES)
def test_package_all_reexports_public_names_of_private_modules(package: str) -> None:
    """A private module's names are its package's: ``trackdb._exceptions`` → ``trackdb``,
    ``onboard.vc._exceptions`` → ``onboard.vc``."""
    for name in _modules(package):
        parent, _, stem = name.rpartition(".")
        if stem.startswith("_"):
            module = importlib.import_module(name)
            exported = set(importlib.import_module(parent).__all__)
            assert set(module.__all__) <= exported, name


@pytest.mark.parametrize("package", ["onboard", "deploy"])
def test_one_exception_root_per_package(package: str) -> None:
    """Every exception class a package defines derives from the package's root (drawn in its
    ``_exceptions`` module), besides the built-in it extends."""
    root = importlib.import_module(f"{package}._exceptions")
    base = getattr(root, f"{package.capitalize()}Error")
    strays = []
    for name in _modules(package):
        module = importlib.import_module(name)
        for value in vars(module).values():
            defined_here = isinstance(value, type) and value.__module__ == name
            if defined_here and issubclass(value, Exception) and not issubclass(value, base):
                strays.append(f"{name}.{value.__name__}")
    assert strays == []


# One home for the physical constants (docs/decisions.md, "One home for the vehicle's data and
# the physical constants"): protocol.units holds GRAVITY_MPS2, MPS_PER_KMH and J_PER_KWH; every
# other module imports them.
CONVERSION_NAMES = frozenset(
    {
        "GRAVITY",
        "GRAVITY_MPS2",
        "G_MPS2",
        "J_PER_KWH",
        "KMH",
        "KMH_PER_MPS",
        "MPS_PER_KMH",
        "MPS_TO_KMH",
        "KMH_TO_MPS",
    }
)
CONSTANT_VALUES = (9.81, 9.80665, 3.6, 1.0 / 3.6, 3.6e6)
UNITS_HOME = ROOT / "protocol" / "units.py"


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


def _inline_constants(path: Path) -> list[int]:
    """Lines of ``path`` that write gravity or a unit factor as a number in an expression."""
    tree = ast.parse(path.read_text(), filename=str(path))
    return [
        node.lineno
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, int | float)
        and not isinstance(node.value, bool)
        and any(math.isclose(float(node.value), c, rel_tol=1e-12) for c in CONSTANT_VALUES)
    ]


def _package_modules() -> list[Path]:
    paths = (path for package in PACKAGES for path in sorted((ROOT / package).rglob("*.py")))
    return [path for path in paths if path != UNITS_HOME]


def test_no_package_defines_a_gravity_or_unit_constant_of_its_own() -> None:
    offenders = [
        f"{path.relative_to(ROOT)}: {name}"
        for path in _package_modules()
        for name in _own_constants(path)
    ]
    assert offenders == []


def test_no_package_writes_gravity_or_a_unit_factor_inline() -> None:
    offenders = [
        f"{path.relative_to(ROOT)}:{line}"
        for path in _package_modules()
        for line in _inline_constants(path)
    ]
    assert offenders == []


def test_the_inline_rule_catches_a_literal(tmp_path: Path) -> None:
    sample = tmp_path / "x.py"
    sample.write_text("e_kwh = e_j / 3.6e6\nv = (0.0, -9.81)\nt_s = 3.5\nok = True\n")
    assert _inline_constants(sample) == [1, 2]


def test_the_constant_rule_catches_a_copy(tmp_path: Path) -> None:
    sample = tmp_path / "x.py"
    sample.write_text(
        "GRAVITY_MPS2 = 9.81\nKMH = 1.0 / 3.6\nG = 9.81\n"
        "class C:\n    to_kmh: float = 3.6\n"
        "LIMIT_MPS = 30.0 / 3.6\nfrom protocol.units import MPS_PER_KMH as KMH\n"
    )
    assert _own_constants(sample) == ["GRAVITY_MPS2", "KMH", "G", "to_kmh"]


def test_units_have_one_home() -> None:
    import onboard.etcs
    from onboard.etcs import values as etcs_values
    from onboard.plant import point_mass
    from protocol import units
    from trackdb import journey, vehicle

    assert point_mass.GRAVITY_MPS2 is units.GRAVITY_MPS2
    assert not hasattr(etcs_values, "KMH")  # one name per conversion: units.MPS_PER_KMH
    assert "KMH" not in onboard.etcs.__all__
    assert point_mass.URV_PARAMETERS is vehicle.URV_PARAMETERS
    assert journey.URV_LIMITS.mass_kg == vehicle.URV_PARAMETERS.mass_kg
    assert journey.URV_LIMITS.max_traction_power_w == vehicle.URV_PARAMETERS.max_traction_power_w


# The bench leaves the train (issue 17 item 5): onboard/ holds only what runs in the onboard
# process; whatever drives or scores a part for tests and benches lives in deploy/bench/.
HARNESS_STEMS = frozenset(
    {
        "bench",
        "catalogue",
        "closed_loop",
        "drive",
        "harness",
        "lockstep",
        "manoeuvres",
        "mission",
        "plots",
        "recording",
        "responder",
        "runner",
        "scenarios",
    }
)
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
    assert _is_harness_name("runner")
    assert _is_harness_name("vc_catalogue")
    assert not _is_harness_name("listener")
    assert not _is_harness_name("driving_function")


# The truth boundary (ARCHITECTURE.md, issue 17 item 1): only ``onboard/plant/`` reads the
# vehicle's true state. Every other onboard module sees the train through the plant's public
# outputs (``onboard.plant.readings``), the actuator interface it commands, and vehicle data
# (parameters, sensor settings). The node, the process's composition root, holds the simulated
# vehicle but may only step it and take its outputs (docs/truth_boundary.md).
ONBOARD = ROOT / "onboard"
PLANT = "onboard.plant"

PUBLIC_OUTPUTS = f"{PLANT}.readings"
"""Any name of this module may be imported: it is what the sensors deliver."""
NOT_TRUTH = frozenset(
    {
        # The actuator interface the VCU commands the plant through.
        "ActuatorCommands",
        # Vehicle data: what the vehicle is built as, not what it is doing.
        "PointMassParameters",
        "URV_PARAMETERS",
        "BogieParameters",
        "URV_BOGIE_PARAMETERS",
        "PowertrainParameters",
        "GRAVITY_MPS2",
        "CURVE_COEFFICIENT_M",
        "MIN_POWER_SPEED_MPS",
        # Settings of the sensor models (their noise and injected faults), not their readings.
        "SensorNoise",
        "SensorFaults",
        "TimeWindow",
    }
)
"""Names that may be imported from the rest of ``onboard.plant``."""
COMPOSITION_ROOT = ONBOARD / "node.py"
VEHICLE_OUTPUTS = frozenset(
    {
        "step",
        "take_datagrams",
        "take_wheel_readings",
        "take_balise_detections",
        "take_marker_detections",
        "wheels",
        "drive",
        "powertrain_reading",
        "force_limits_n",
    }
)
"""What the node may touch of the simulated vehicle: stepping it, and its sensors' outputs."""


def truth_imports(source: str) -> list[str]:
    """The imports of ``source`` that reach the plant's truth."""
    leaks = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            module = node.module
            if module == PLANT or module.startswith(f"{PLANT}."):
                if module == PUBLIC_OUTPUTS:
                    continue
                leaks += [f"{module}.{a.name}" for a in node.names if a.name not in NOT_TRUTH]
        elif isinstance(node, ast.Import):
            leaks += [
                alias.name
                for alias in node.names
                if alias.name.startswith(f"{PLANT}.") and alias.name != PUBLIC_OUTPUTS
            ]
    return leaks


def _consumers() -> list[Path]:
    """Every onboard module but the plant and the composition root."""
    return [
        path
        for path in sorted(ONBOARD.rglob("*.py"))
        if ONBOARD / "plant" not in path.parents and path != COMPOSITION_ROOT
    ]


def test_no_onboard_part_but_the_plant_imports_the_truth() -> None:
    offenders = {
        str(path.relative_to(ROOT)): leaks
        for path in _consumers()
        if (leaks := truth_imports(path.read_text()))
    }
    assert offenders == {}


@pytest.mark.parametrize("part", ["etcs", "ato_ob", "adf", "vc", "vcu", "sfa"])
@pytest.mark.parametrize(
    "leak",
    [
        "from onboard.plant.interfaces import BogieTruth",
        "from onboard.plant.sensors import TruthSample",
        "from onboard.plant import PointMassModel",
        "from onboard.plant.vehicle import SimulatedVehicle",
        "import onboard.plant.bogie",
    ],
)
def test_a_deliberate_truth_import_is_caught(tmp_path: Path, part: str, leak: str) -> None:
    module = tmp_path / "onboard" / part / "leak.py"
    module.parent.mkdir(parents=True)
    module.write_text(f'"""A part that peeks."""\n\n{leak}\n')
    assert truth_imports(module.read_text()) != []


def test_readings_vehicle_data_and_actuator_commands_are_not_truth() -> None:
    allowed = (
        "from onboard.plant.readings import BaliseDetection, WheelReading\n"
        "from onboard.plant.interfaces import ActuatorCommands\n"
        "from onboard.plant import URV_PARAMETERS, PointMassParameters\n"
    )
    assert truth_imports(allowed) == []


def _touched_on_the_vehicle(source: str) -> set[str]:
    """Attributes the source reads or calls on ``self.plant`` or a local ``plant``."""
    touched = set()
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Attribute):
            continue
        value = node.value
        on_self = (
            isinstance(value, ast.Attribute)
            and value.attr == "plant"
            and isinstance(value.value, ast.Name)
            and value.value.id == "self"
        )
        if on_self or (isinstance(value, ast.Name) and value.id == "plant"):
            touched.add(node.attr)
    return touched


def test_the_node_only_steps_the_vehicle_and_takes_its_outputs() -> None:
    touched = _touched_on_the_vehicle(COMPOSITION_ROOT.read_text())
    assert touched
    assert touched <= VEHICLE_OUTPUTS, sorted(touched - VEHICLE_OUTPUTS)


def test_the_node_check_catches_a_read_of_the_truth() -> None:
    peek = "class N:\n    def f(self):\n        return self.plant.position_m\n"
    assert _touched_on_the_vehicle(peek) == {"position_m"}
