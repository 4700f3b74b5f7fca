"""Scenarios: the file format, its loader, the library, the runner, its KPIs and reports."""

from deploy.scenario.conditions import Condition, parse_condition
from deploy.scenario.loader import (
    SCENARIO_DIR,
    ScenarioFileError,
    load_scenario,
    parse_scenario,
    scenario_names,
)
from deploy.scenario.schema import (
    Action,
    Expectation,
    Fault,
    JourneySpec,
    OperatorSpec,
    ScenarioSpec,
    VehicleSpec,
)

__all__ = [
    "SCENARIO_DIR",
    "Action",
    "Condition",
    "Expectation",
    "Fault",
    "JourneySpec",
    "OperatorSpec",
    "ScenarioFileError",
    "ScenarioSpec",
    "VehicleSpec",
    "load_scenario",
    "parse_condition",
    "parse_scenario",
    "scenario_names",
]
