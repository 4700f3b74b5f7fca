"""The truth boundary (ARCHITECTURE.md): only ``onboard/plant/`` reads the vehicle's true state.

Every other onboard module sees the train through the plant's public outputs
(:mod:`onboard.plant.readings`), the actuator interface it commands, and vehicle data
(parameters, sensor settings). The node, the process's composition root, holds the simulated
vehicle but may only step it and take its outputs.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ONBOARD = ROOT / "onboard"
PLANT = "onboard.plant"

PUBLIC_OUTPUTS = f"{PLANT}.readings"
"""Any name of this module may be imported: it is what the sensors deliver."""
NOT_TRUTH = frozenset({
    # The actuator interface the VCU commands the plant through.
    "ActuatorCommands",
    # Vehicle data: what the vehicle is built as, not what it is doing.
    "PointMassParameters", "URV_PARAMETERS", "BogieParameters", "URV_BOGIE_PARAMETERS",
    "PowertrainParameters", "GRAVITY_MPS2", "CURVE_COEFFICIENT_M", "MIN_POWER_SPEED_MPS",
    # Settings of the sensor models (their noise and injected faults), not their readings.
    "SensorNoise", "SensorFaults", "TimeWindow",
})  # fmt: skip
"""Names that may be imported from the rest of ``onboard.plant``."""
COMPOSITION_ROOT = ONBOARD / "node.py"
VEHICLE_OUTPUTS = frozenset({
    "step", "take_datagrams", "take_wheel_readings", "take_balise_detections", "wheels", "drive",
    "powertrain_reading", "force_limits_n",
})  # fmt: skip
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
    assert touched and touched <= VEHICLE_OUTPUTS, sorted(touched - VEHICLE_OUTPUTS)


def test_the_node_check_catches_a_read_of_the_truth() -> None:
    peek = "class N:\n    def f(self):\n        return self.plant.position_m\n"
    assert _touched_on_the_vehicle(peek) == {"position_m"}
