"""What the parts of one whole-stack run share: the scenario, the node, the telemetry, the log.

A run (``deploy.scenario.runner``) is made of a trackside harness
(``deploy.scenario.trackside_harness``), a fault injector (``deploy.scenario.fault_injector``),
an operator script (``deploy.scenario.operator_script``) and an outcome builder
(``deploy.scenario.outcome``). Each takes this :class:`RunContext`, which holds the one copy of
what they read and write: the actions done and the failures found, the operator's presence at
the console, the sessions' outages, and the wall time spent stepping the node.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from deploy._exceptions import DeployError
from deploy.scenario.schema import ScenarioSpec
from deploy.scenario.telemetry import TelemetryRecorder
from onboard.node import OnboardNode

__all__ = [
    "LINK_WAIT_S",
    "WAIT_S",
    "ActionLog",
    "RunContext",
    "RunOptions",
    "ScenarioRunError",
    "forward_m",
    "wait_for",
]

WAIT_S = 10.0
"""How long, in wall time, a message sent to the vehicle may take to reach it [s]."""
LINK_WAIT_S = 15.0
"""How long, in wall time, the sessions may take to notice a cut or a restored link [s]."""


class ScenarioRunError(DeployError, RuntimeError):
    """The run could not be carried out (not: an expectation failed)."""


@dataclass(frozen=True)
class RunOptions:
    fast: bool = True
    """Lockstep, as fast as possible; otherwise paced at wall time × ``speed``."""
    speed: float = 1.0
    seed: int | None = None
    """Overrides the scenario's seed."""
    report_dir: Path | None = None
    insecure: bool = False
    """Plain TCP between the trackside and the onboard (debugging only); by default TLS with
    certificates of a CA made for the run, the trackside's session enforcing the access
    control (docs/security.md)."""
    database_url: str | None = None
    """Where a scenario's ``line = "ID"`` that is not built in is read (SQLAlchemy URL; ``ato
    run`` passes ``ATO_DATABASE_URL``, else the trackside's default); None: built-in lines
    only (``deploy.scenario.line_source``)."""


@dataclass
class ActionLog:
    """An action of the operator, the RBC or the link, as it was done."""

    action: str
    at_s: float
    accepted: bool
    detail: str | None = None


@dataclass
class RunContext:
    """One run's shared state (see the module docstring)."""

    spec: ScenarioSpec
    options: RunOptions
    seed: int
    node: OnboardNode
    recorder: TelemetryRecorder
    actions: list[ActionLog] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    operator_present: bool = False
    """Whether the operator is at the console and sees the vehicle (faults take him away)."""
    session_outages: list[dict[str, float | None]] = field(default_factory=list)
    """Each loss of an established session: when [s], and when one was established again."""
    lockstep_wall_s: float = 0.0
    """Wall time spent stepping the node (the rest is set-up, operator and REST)."""

    @property
    def now_s(self) -> float:
        return self.node.clock.now_s

    def run_for(self, duration_s: float) -> None:
        """Step the node ``duration_s`` of simulated time, timing it."""
        started = time.perf_counter()
        self.node.run(duration_s)
        self.lockstep_wall_s += time.perf_counter() - started

    def log(
        self, action: str, accepted: bool, detail: str | None = None, *, at_s: float | None = None
    ) -> None:
        """Log an action done at ``at_s`` [s] (default: now)."""
        self.actions.append(
            ActionLog(action, self.now_s if at_s is None else at_s, accepted, detail)
        )


def wait_for(
    condition: Callable[[], bool],
    worker: threading.Thread | None = None,
    timeout_s: float = WAIT_S,
) -> bool:
    """Wait in wall time (the simulation stands still) until ``condition`` holds; False when
    it does not within ``timeout_s`` or ``worker`` ends first."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline or (worker is not None and not worker.is_alive()):
            return condition()
        time.sleep(0.0005)
    return True


def forward_m(node: OnboardNode, from_m: float, to_m: float) -> float:
    """Along the line from ``from_m`` to ``to_m`` (round the ring if need be) [m]."""
    if node.track_map.line.ring:
        return (to_m - from_m) % node.track_map.length_m
    return to_m - from_m
