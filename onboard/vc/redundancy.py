"""Two VC replicas in 2-out-of-2, and the watchdog that cuts the valves' power (DOMAIN.md §7.2).

Beyond the seeds' single board (issue 7, item 4): two :class:`~onboard.vc.module.VitalControl`
replicas run on the same inputs, each with its own output stage (its
:class:`~onboard.vc.hardware.EmergencyBrakeValves` emulator stands for its contact in the
valves' series power chain). :class:`TwoOutOfTwo` keeps the vehicle's valves energised only
while

- both replicas keep their contacts closed (either one demanding EB brakes),
- their voted outputs (:class:`ReplicaView`) agree, or disagree for no longer than
  ``disagreement_tolerance_s``, and
- each replica's :class:`Watchdog` was kicked (by its Task B) within ``watchdog_timeout_s``.

A disagreement or a watchdog expiry *trips* the pair: the valves stay de-energised until a
restart (like System Decay). Everything takes the simulated time; nothing reads a clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum

from onboard.runtime import Executive
from onboard.runtime.clock import NS_PER_S
from onboard.vc._exceptions import VcInputError
from onboard.vc.config import TIME_TOLERANCE_S
from onboard.vc.fsm import BrakeState, EtcsState, TaskAState, TaskBState
from onboard.vc.hardware import EmergencyBrakeValves
from onboard.vc.module import (
    TASK_A_PRIORITY,
    TASK_B_PRIORITY,
    TASK_C_PRIORITY,
    VcOutputs,
    VitalControl,
)
from onboard.vc.quiet import skips_quiet_cycles
from onboard.vc.tick import QuietTick

__all__ = [
    "VOTER_PRIORITY",
    "PairEvent",
    "PairEventKind",
    "RedundancyConfig",
    "ReplicaFault",
    "ReplicaFaultKind",
    "ReplicaView",
    "TwoOutOfTwo",
    "Watchdog",
]

VOTER_PRIORITY = 15
"""Below both replicas' Task C (20), above their Task A (10): the vote sees this tick's outputs."""


@dataclass(frozen=True, kw_only=True)
class RedundancyConfig:
    """The pair's parameters."""

    period_s: float = 0.002
    """The voter's and the watchdog's check period [s] (Task B's)."""
    disagreement_tolerance_s: float = 0.010
    """⚠ How long the replicas' voted outputs may differ before the pair trips [s]."""
    watchdog_timeout_s: float = 0.010
    """⚠ How long a replica may go without kicking its watchdog [s] (five Task B periods)."""

    def __post_init__(self) -> None:
        for name in ("period_s", "disagreement_tolerance_s", "watchdog_timeout_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise VcInputError(f"{name} must be finite and not negative, got {value}")
        if self.period_s <= 0.0:
            raise VcInputError(f"period_s must be positive, got {self.period_s}")


class Watchdog:
    """Expires when not kicked for longer than ``timeout_s``; latched once expired."""

    def __init__(self, timeout_s: float, *, start_s: float = 0.0) -> None:
        if not (math.isfinite(timeout_s) and timeout_s > 0.0):
            raise VcInputError(f"a watchdog needs a positive timeout, got {timeout_s}")
        self.timeout_s = timeout_s
        self.last_kick_s = start_s
        self.expired_at_s: float | None = None

    def kick(self, now_s: float) -> None:
        """The replica answered at ``now_s`` (no effect once expired)."""
        if self.expired_at_s is None:
            self.last_kick_s = max(self.last_kick_s, now_s)

    def check(self, now_s: float) -> bool:
        """True once ``now_s`` is more than ``timeout_s`` past the last kick (latched)."""
        if self.expired_at_s is None and now_s - self.last_kick_s > self.timeout_s + (
            TIME_TOLERANCE_S
        ):
            self.expired_at_s = now_s
        return self.expired_at_s is not None


class ReplicaFaultKind(StrEnum):
    HALT = "halt"
    """The board stops: its three tasks no longer run (its outputs freeze, no more kicks)."""


@dataclass(frozen=True, kw_only=True)
class ReplicaFault:
    """Replica ``replica`` (0 or 1) misbehaves in ``[start_s, end_s)``."""

    kind: ReplicaFaultKind
    replica: int
    start_s: float
    end_s: float = math.inf

    def __post_init__(self) -> None:
        if self.replica not in (0, 1):
            raise VcInputError(f"a pair has replicas 0 and 1, got {self.replica}")
        if not (math.isfinite(self.start_s) and self.end_s > self.start_s):
            raise VcInputError(f"a fault window needs start < end, got {self.start_s}")

    def active(self, now_s: float) -> bool:
        return self.start_s <= now_s < self.end_s


@dataclass(frozen=True, slots=True, kw_only=True)
class ReplicaView:
    """What the two replicas must agree on: their commands and their states."""

    eb_commanded: bool
    system_decay: bool
    etcs_isolated: bool
    task_a_state: TaskAState
    task_b_state: TaskBState
    brake_state: BrakeState
    etcs_state: EtcsState
    standstill: bool
    odometry_efficient: bool

    @classmethod
    def of(cls, outputs: VcOutputs) -> ReplicaView:
        return cls(
            eb_commanded=outputs.eb_commanded,
            system_decay=outputs.system_decay,
            etcs_isolated=outputs.etcs_isolated,
            task_a_state=outputs.task_a_state,
            task_b_state=outputs.task_b_state,
            brake_state=outputs.brake_state,
            etcs_state=outputs.etcs_state,
            standstill=outputs.standstill,
            odometry_efficient=outputs.odometry_efficient,
        )

    def differences(self, other: ReplicaView) -> tuple[str, ...]:
        """The names of the fields that differ."""
        return tuple(name for name in self.__slots__ if getattr(self, name) != getattr(other, name))


class PairEventKind(StrEnum):
    REPLICA_EB = "replica_eb"
    """A replica opened its contact (demanded EB): the vehicle brakes."""
    DISAGREEMENT = "disagreement"
    """The voted outputs differed for longer than the tolerance: the pair trips."""
    WATCHDOG_EXPIRED = "watchdog_expired"
    """A replica stopped kicking its watchdog: the pair trips."""


@dataclass(frozen=True, slots=True, kw_only=True)
class PairEvent:
    time_s: float
    kind: PairEventKind
    replica: int | None
    detail: str


class TwoOutOfTwo:
    """Two replicas in 2-out-of-2 driving the vehicle's valves, with one watchdog each.

    Parameters
    ----------
    replicas
        The two VCs, built on the same inputs (each with its own hardware ports).
    valves
        The vehicle's EB valves and brake pipe: energised only when the pair allows it.
    config
        Tolerance window and watchdog timeout.
    faults
        Replica faults to inject (tests, scenarios).
    start_s
        Power-up time [s].
    """

    def __init__(
        self,
        replicas: tuple[VitalControl, VitalControl],
        *,
        valves: EmergencyBrakeValves,
        config: RedundancyConfig | None = None,
        faults: Sequence[ReplicaFault] = (),
        start_s: float = 0.0,
    ) -> None:
        self.replicas = replicas
        self.valves = valves
        self.config = config or RedundancyConfig()
        self.faults = tuple(faults)
        self.watchdogs = tuple(
            Watchdog(self.config.watchdog_timeout_s, start_s=start_s) for _ in replicas
        )
        self.events: list[PairEvent] = []
        self.tripped_by: PairEventKind | None = None
        self.disagreeing_since_s: float | None = None
        self._contacts_open = [True, True]
        self.tick: QuietTick | None = None
        """The replicas' B and C and this voter as one sleeping task (lockstep)."""

    @property
    def tripped(self) -> bool:
        return self.tripped_by is not None

    @property
    def eb_commanded(self) -> bool:
        """The vehicle's valves are de-energised."""
        return not self.valves.energised

    def halted(self, replica: int, now_s: float) -> bool:
        return any(
            f.kind is ReplicaFaultKind.HALT and f.replica == replica and f.active(now_s)
            for f in self.faults
        )

    def register(
        self, executive: Executive, *, phase_s: float = 0.0, event_driven: bool | None = None
    ) -> None:
        """Add ``vc0.B``, ``vc0.C``, ``vc0.A``, the same for ``vc1``, and ``vc.2oo2``.

        ``event_driven``: B and C skip their quiet cycles (None: in lockstep only)."""
        skip = skips_quiet_cycles(executive, event_driven)
        for replica in self.replicas:
            replica.skip_quiet_cycles(skip)
        if skip and not self.faults and self._one_period():
            self._register_tick(executive, phase_s)
            return
        for index, replica in enumerate(self.replicas):
            config = replica.config
            tasks: tuple[tuple[str, Callable[[float], object], float, int], ...] = (
                (
                    "B",
                    self._kicking(index, replica.task_b.step),
                    config.task_b_period_s,
                    TASK_B_PRIORITY,
                ),
                ("C", replica.task_c.step, config.task_c_period_s, TASK_C_PRIORITY),
                ("A", replica.task_a.step, config.task_a_period_s, TASK_A_PRIORITY),
            )
            for letter, step, period_s, priority in tasks:
                executive.add_task(
                    f"vc{index}.{letter}",
                    self._unless_halted(index, step),
                    period_s=period_s,
                    phase_s=phase_s,
                    priority=priority,
                )
        executive.add_task(
            "vc.2oo2",
            lambda release_ns: self.step(release_ns / NS_PER_S),
            period_s=self.config.period_s,
            phase_s=phase_s,
            priority=VOTER_PRIORITY,
        )

    def _one_period(self) -> bool:
        """B, C and the voter share one period (a condition of :class:`QuietTick`)."""
        return all(
            r.config.task_b_period_s == r.config.task_c_period_s == self.config.period_s
            for r in self.replicas
        )

    def _register_tick(self, executive: Executive, phase_s: float) -> None:
        """``vc.tick`` (each B, each C, the voter, asleep while quiet), ``vc0.A``, ``vc1.A``:
        in lockstep, with no replica fault to inject."""
        tick = QuietTick(self.replicas, pair=self)
        self.tick = tick
        tick.register(
            executive,
            period_s=self.config.period_s,
            phase_s=phase_s,
            priority=TASK_B_PRIORITY,
            task_a=tuple(
                (
                    f"vc{index}.A",
                    self._unless_halted(index, replica.task_a.step),
                    replica.config.task_a_period_s,
                    TASK_A_PRIORITY,
                )
                for index, replica in enumerate(self.replicas)
            ),
        )

    def _kicking(self, index: int, step: Callable[[float], object]) -> Callable[[float], object]:
        def run(now_s: float) -> None:
            step(now_s)
            self.watchdogs[index].kick(now_s)

        return run

    def _unless_halted(self, index: int, step: Callable[[float], object]) -> Callable[[int], None]:
        if not any(f.kind is ReplicaFaultKind.HALT and f.replica == index for f in self.faults):

            def always(release_ns: int) -> None:  # never halted: no faults to look through
                step(release_ns / NS_PER_S)

            return always

        def run(release_ns: int) -> None:
            now_s = release_ns / NS_PER_S
            if not self.halted(index, now_s):
                step(now_s)

        return run

    def step(self, now_s: float) -> None:
        """Vote on the replicas' last outputs, check the watchdogs, drive the valves."""
        for index, replica in enumerate(self.replicas):
            contact_open = not replica.hardware.valves.energised
            if contact_open and not self._contacts_open[index]:
                self._event(now_s, PairEventKind.REPLICA_EB, index, "contact opened")
            self._contacts_open[index] = contact_open
            if self.watchdogs[index].check(now_s) and not self.tripped:
                last = self.watchdogs[index].last_kick_s
                self._trip(now_s, PairEventKind.WATCHDOG_EXPIRED, index, f"last kick {last:.3f} s")
        # The vote's key first (cheap); the fields that differ only when they do.
        differences: tuple[str, ...] = ()
        if self.replicas[0].vote_key() != self.replicas[1].vote_key():
            first, second = (ReplicaView.of(replica.outputs) for replica in self.replicas)
            differences = first.differences(second)
        if not differences:
            self.disagreeing_since_s = None
        elif self.disagreeing_since_s is None:
            self.disagreeing_since_s = now_s
        elif (
            now_s - self.disagreeing_since_s
            > self.config.disagreement_tolerance_s + TIME_TOLERANCE_S
            and not self.tripped
        ):
            self._trip(now_s, PairEventKind.DISAGREEMENT, None, ", ".join(differences))
        energised = not self.tripped and not any(self._contacts_open)
        self.valves.command(energised, now_s)

    def _trip(self, now_s: float, kind: PairEventKind, replica: int | None, detail: str) -> None:
        self.tripped_by = kind
        self._event(now_s, kind, replica, detail)

    def _event(self, now_s: float, kind: PairEventKind, replica: int | None, detail: str) -> None:
        self.events.append(PairEvent(time_s=now_s, kind=kind, replica=replica, detail=detail))
