"""The catalogue is run once per session; its report is printed at the end of the run."""

from __future__ import annotations

import pytest

from onboard.vc import CATALOGUE, ScenarioResult, format_report, run_catalogue

_RESULTS: list[ScenarioResult] = []


@pytest.fixture(scope="session")
def catalogue_results() -> dict[str, ScenarioResult]:
    """Every scenario of the catalogue, run in lockstep, by key."""
    if not _RESULTS:
        _RESULTS.extend(run_catalogue(CATALOGUE))
    return {result.key: result for result in _RESULTS}


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if _RESULTS:
        terminalreporter.section("VC scenario catalogue (onboard/vc)")
        terminalreporter.write_line(format_report(_RESULTS))
