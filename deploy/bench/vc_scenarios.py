"""Scenario definitions for the VC: what to inject when, and the outcome class expected.

A :class:`Scenario` is declarative: the remote driver's speed targets, the operator's actions,
the faults (on the link, in the ATO-OB, on the tachometer board, the relay, the brake pipe),
balise telegrams, and the outcome class the seeds' taxonomy expects (seed 001 §IV.B:
none / EB with safe recovery / EB then System Decay / System Decay at standstill). Its
:class:`Hazard` says from when intervention times are measured. The catalogue is in
:mod:`deploy.bench.vc_catalogue`; :mod:`deploy.bench.vc_runner` runs one in lockstep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

from deploy._exceptions import DeployError
from deploy.bench.vc_responder import OperatorAction, ResponderFault
from onboard.vc.config import VcConfig
from onboard.vc.hardware import FULL_EB_DELAY_S, PipeFault, RelayFault, TachometerFault
from onboard.vc.link import LinkFault

__all__ = [
    "SEED_HAZARDOUS_COUNTS",
    "SEED_SCENARIO_COUNT",
    "Fault",
    "Hazard",
    "HazardKind",
    "OutcomeClass",
    "Scenario",
    "ScenarioError",
    "SpeedTarget",
]


class ScenarioError(DeployError, ValueError):
    """A scenario of the catalogue that cannot be run: a fault window that ends before it
    starts, an action after the run."""


class OutcomeClass(StrEnum):
    """The seeds' classes of a scenario's outcome (seed 001 §IV.B, seed 004 Fig. 7)."""

    NONE = "none"
    EB_SAFE_RECOVERY = "eb_safe_recovery"
    """EB, then the rearm once safe and confirmed."""
    EB_THEN_DECAY = "eb_then_decay"
    """EB on a moving train, and System Decay."""
    DECAY_AT_STANDSTILL = "decay_at_standstill"
    """System Decay with the train already stopped: no braking intervention."""


SEED_SCENARIO_COUNT = 36
SEED_HAZARDOUS_COUNTS = {
    OutcomeClass.EB_SAFE_RECOVERY: 5,
    OutcomeClass.EB_THEN_DECAY: 10,
    OutcomeClass.DECAY_AT_STANDSTILL: 8,
}
"""36 scenarios, 23 hazardous: 5 + 10 + 8 (seed 001 §IV.B)."""


class HazardKind(StrEnum):
    AT = "at"
    """At ``Hazard.at_s``: a fault's start, an operator's action, a time limit's expiry."""
    OVERSPEED = "overspeed"
    """When the true speed first exceeds the VC's limit with ETCS isolated."""
    RELAY_COMMAND = "relay_command"
    """When Task C first commands the ETCS relay (the actuation that fails)."""
    REARM_COMMAND = "rearm_command"
    """When Task C first energises the valves at or after ``at_s`` (the rearm that fails)."""


@dataclass(frozen=True, kw_only=True)
class Hazard:
    kind: HazardKind
    at_s: float = 0.0


@dataclass(frozen=True, kw_only=True)
class SpeedTarget:
    """From ``from_s`` on, the remote driver asks for ``speed_kmh``."""

    from_s: float
    speed_kmh: float


Fault = LinkFault | ResponderFault | TachometerFault | RelayFault | PipeFault


@dataclass(frozen=True, kw_only=True)
class Scenario:
    """One scenario of the catalogue."""

    key: str
    """Short name: the seeds' letter where it has one (A, B, ..., N), else a descriptive key."""
    title: str
    expected: OutcomeClass
    duration_s: float
    hazard: Hazard | None = None
    driver: tuple[SpeedTarget, ...] = ()
    operator: tuple[OperatorAction, ...] = ()
    auto_confirm_rearm: bool = True
    faults: tuple[Fault, ...] = ()
    balise_telegrams: tuple[tuple[float, int], ...] = ()
    """(time [s], NID_BG) of the balise groups the BTM reads."""
    etcs_inserted_at_start: bool = True
    link_delay_s: float = 0.001
    """Each direction's nominal travel time [s]."""
    full_eb_delay_s: float = FULL_EB_DELAY_S
    """From the valves' de-energising to full EB with the pipe charged [s] (450 ms, seed 004)."""
    config: VcConfig = field(default_factory=VcConfig)
    seed_letter: str | None = None
    """The letter of seed 001/004 this scenario reproduces, if any."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ScenarioError(f"{self.key}: the duration must be positive")
        times = [a.at_s for a in self.operator] + [t.from_s for t in self.driver]
        times += [t for t, _ in self.balise_telegrams]
        if any(not 0 <= t < self.duration_s for t in times):
            raise ScenarioError(f"{self.key}: an action or target outside [0, duration)")
