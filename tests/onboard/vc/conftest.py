"""The catalogue is run once per session (on one VC, on a 2oo2 pair, and with the fused speed);
its reports are printed at the end of the run."""

from __future__ import annotations

import pytest

from deploy.bench.vc_catalogue import CATALOGUE
from deploy.bench.vc_fused_speed import (
    FusedComparison,
    compare_fused_speed,
    format_fused_comparison,
)
from deploy.bench.vc_runner import ScenarioResult, format_report, run_catalogue, run_scenario

_RESULTS: list[ScenarioResult] = []
_PAIR_RESULTS: list[ScenarioResult] = []
_FUSED: list[FusedComparison] = []


@pytest.fixture(scope="session")
def catalogue_results() -> dict[str, ScenarioResult]:
    """Every scenario of the catalogue, run in lockstep, by key."""
    if not _RESULTS:
        _RESULTS.extend(run_catalogue(CATALOGUE))
    return {result.key: result for result in _RESULTS}


@pytest.fixture(scope="session")
def pair_results() -> dict[str, ScenarioResult]:
    """Every scenario of the catalogue on two VCs in 2-out-of-2, by key."""
    if not _PAIR_RESULTS:
        _PAIR_RESULTS.extend(run_scenario(s, replicas=2) for s in CATALOGUE)
    return {result.key: result for result in _PAIR_RESULTS}


@pytest.fixture(scope="session")
def fused_comparison() -> dict[str, FusedComparison]:
    """The odometry-driven scenarios with the tachometer alone and with the fused speed."""
    if not _FUSED:
        _FUSED.extend(compare_fused_speed())
    return {item.key: item for item in _FUSED}


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if _RESULTS:
        terminalreporter.section("VC scenario catalogue (onboard/vc)")
        terminalreporter.write_line(format_report(_RESULTS))
    if _PAIR_RESULTS:
        same = sum(a.outcome is b.outcome for a, b in zip(_RESULTS, _PAIR_RESULTS, strict=False))
        trips = sum(any(e.kind.value != "replica_eb" for e in r.pair_events) for r in _PAIR_RESULTS)
        terminalreporter.write_line(
            f"\n2oo2 pair: {same} of {len(_PAIR_RESULTS)} scenarios in the same class as one VC, "
            f"{trips} tripped by a disagreement or a watchdog"
        )
    if _FUSED:
        terminalreporter.write_line("")
        terminalreporter.write_line(format_fused_comparison(_FUSED))
