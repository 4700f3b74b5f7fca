"""The three FSMs of the Vital Control (seed 004 §2.4), as explicit transition tables.

Seed 004 designs the application logic as three Stateflow FSMs, exported as Tasks A, B and C.
Ours are tables: rows in priority order, from a state the first row whose trigger holds is
taken, at most one row per region and cycle. A row with several sources is one transition (a
superstate's arrow in Stateflow); transition coverage counts rows, and also (row, source)
pairs. Task C runs two parallel regions, the brake and the ETCS relay.

Task A, the request composer (what to ask the ATO-OB):

===  ===========================================  =============  =========================
no.  from                                         to             trigger
===  ===========================================  =============  =========================
A1   SUPERVISING BRAKED REARM_PENDING             DECAYED        system_decay
A2   SUPERVISING                                  BRAKED         eb_applied
A3   BRAKED                                       REARM_PENDING  rearm_possible
A4   REARM_PENDING                                BRAKED         rearm_aborted
A5   REARM_PENDING                                SUPERVISING    eb_released
===  ===========================================  =============  =========================

Task B, the supervisor (the EB flag and System Decay):

===  ===========================================  =============  =========================
B1   MONITORING EB_DEMANDED                       DECAYED        decay_condition (2, 3, 4)
B2   MONITORING                                   EB_DEMANDED    eb_condition (1, 5, 6)
B3   EB_DEMANDED                                  MONITORING     hazard_cleared_at_standstill
===  ===========================================  =============  =========================

Task C, brake region (the solenoid valves):

===  ===========================================  =============  =========================
C1   RELEASED BRAKING STANDSTILL REARMING         DECAYED        system_decay
C2   REARMING                                     DECAYED        rearm_not_applied
C3   RELEASED REARMING                            BRAKING        eb_flag
C4   BRAKING                                      STANDSTILL     standstill
C5   STANDSTILL                                   REARMING       rearm_confirmed
C6   REARMING                                     RELEASED       rearm_verified
===  ===========================================  =============  =========================

Task C, ETCS region (the radio relay):

===  ===========================================  =============  =========================
E1   INSERTED                                     ISOLATING      isolation_confirmed
E2   ISOLATING                                    ISOLATED       isolation_verified
E3   ISOLATING                                    FAILED         isolation_not_actuated
E4   ISOLATED                                     INSERTING      insertion_confirmed
E5   INSERTING                                    INSERTED       insertion_verified
E6   INSERTING                                    FAILED         insertion_not_actuated
===  ===========================================  =============  =========================

Power-up states: A BRAKED, B MONITORING, C brake BRAKING (the valves are de-energised until
the first rearm), C ETCS INSERTED or ISOLATED as the relay reads.
"""

from __future__ import annotations

from collections.abc import Iterable, Set
from dataclasses import dataclass
from enum import StrEnum
from typing import Generic, TypeVar

__all__ = [
    "ALL_TABLES",
    "TASK_A_TRANSITIONS",
    "TASK_B_TRANSITIONS",
    "TASK_C_BRAKE_TRANSITIONS",
    "TASK_C_ETCS_TRANSITIONS",
    "BrakeState",
    "EtcsState",
    "Fsm",
    "FsmCoverage",
    "FsmTransition",
    "StateMachine",
    "TaskAState",
    "TaskBState",
    "TransitionRule",
    "Trigger",
    "select_rule",
    "transition_coverage",
]


class Fsm(StrEnum):
    """The FSMs (and Task C's two regions)."""

    TASK_A = "A"
    TASK_B = "B"
    TASK_C_BRAKE = "C.brake"
    TASK_C_ETCS = "C.etcs"


class TaskAState(StrEnum):
    SUPERVISING = "supervising"
    """EB released: vitality, EB release, vigilance; ETCS queries at standstill."""
    BRAKED = "braked"
    """EB applied, rearm not possible yet."""
    REARM_PENDING = "rearm_pending"
    """EB applied at standstill and safe: the EB Rearm Confirmation is asked."""
    DECAYED = "decayed"
    """System Decay: only vitality and the notifications until a restart."""


class TaskBState(StrEnum):
    MONITORING = "monitoring"
    EB_DEMANDED = "eb_demanded"
    """The EB flag is up (latched until the hazard has gone and the train stands)."""
    DECAYED = "decayed"


class BrakeState(StrEnum):
    RELEASED = "released"
    """Valves energised, brake pipe charged: traction possible."""
    BRAKING = "braking"
    """Valves de-energised, waiting for standstill."""
    STANDSTILL = "standstill"
    """EB applied at standstill, waiting for a safe and confirmed rearm."""
    REARMING = "rearming"
    """Valves energised again, waiting for the EB input to read "released"."""
    DECAYED = "decayed"
    """System Decay: valves de-energised until a restart."""


class EtcsState(StrEnum):
    INSERTED = "inserted"
    ISOLATING = "isolating"
    ISOLATED = "isolated"
    INSERTING = "inserting"
    FAILED = "failed"
    """The relay did not actuate: System Decay."""


class Trigger(StrEnum):
    SYSTEM_DECAY = "system_decay"
    EB_APPLIED = "eb_applied"
    REARM_POSSIBLE = "rearm_possible"
    REARM_ABORTED = "rearm_aborted"
    EB_RELEASED = "eb_released"
    DECAY_CONDITION = "decay_condition"
    EB_CONDITION = "eb_condition"
    HAZARD_CLEARED_AT_STANDSTILL = "hazard_cleared_at_standstill"
    REARM_NOT_APPLIED = "rearm_not_applied"
    EB_FLAG = "eb_flag"
    STANDSTILL = "standstill"
    REARM_CONFIRMED = "rearm_confirmed"
    REARM_VERIFIED = "rearm_verified"
    ISOLATION_CONFIRMED = "isolation_confirmed"
    ISOLATION_VERIFIED = "isolation_verified"
    ISOLATION_NOT_ACTUATED = "isolation_not_actuated"
    INSERTION_CONFIRMED = "insertion_confirmed"
    INSERTION_VERIFIED = "insertion_verified"
    INSERTION_NOT_ACTUATED = "insertion_not_actuated"


S = TypeVar("S", bound=StrEnum)
S_co = TypeVar("S_co", bound=StrEnum, covariant=True)


@dataclass(frozen=True, kw_only=True)
class TransitionRule(Generic[S_co]):
    """One row of a transition table."""

    fsm: Fsm
    number: int
    sources: frozenset[S_co]
    target: S_co
    trigger: Trigger

    @property
    def label(self) -> str:
        prefix = {Fsm.TASK_C_ETCS: "E", Fsm.TASK_C_BRAKE: "C"}.get(self.fsm, self.fsm.value)
        return f"{prefix}{self.number}"


def _rows(fsm: Fsm, *rows: tuple[Iterable[S], S, Trigger]) -> tuple[TransitionRule[S], ...]:
    return tuple(
        TransitionRule(
            fsm=fsm, number=number, sources=frozenset(sources), target=target, trigger=trigger
        )
        for number, (sources, target, trigger) in enumerate(rows, start=1)
    )


_A, _B, _C, _E, _T = TaskAState, TaskBState, BrakeState, EtcsState, Trigger

TASK_A_TRANSITIONS = _rows(
    Fsm.TASK_A,
    ((_A.SUPERVISING, _A.BRAKED, _A.REARM_PENDING), _A.DECAYED, _T.SYSTEM_DECAY),
    ((_A.SUPERVISING,), _A.BRAKED, _T.EB_APPLIED),
    ((_A.BRAKED,), _A.REARM_PENDING, _T.REARM_POSSIBLE),
    ((_A.REARM_PENDING,), _A.BRAKED, _T.REARM_ABORTED),
    ((_A.REARM_PENDING,), _A.SUPERVISING, _T.EB_RELEASED),
)
TASK_B_TRANSITIONS = _rows(
    Fsm.TASK_B,
    ((_B.MONITORING, _B.EB_DEMANDED), _B.DECAYED, _T.DECAY_CONDITION),
    ((_B.MONITORING,), _B.EB_DEMANDED, _T.EB_CONDITION),
    ((_B.EB_DEMANDED,), _B.MONITORING, _T.HAZARD_CLEARED_AT_STANDSTILL),
)
TASK_C_BRAKE_TRANSITIONS = _rows(
    Fsm.TASK_C_BRAKE,
    ((_C.RELEASED, _C.BRAKING, _C.STANDSTILL, _C.REARMING), _C.DECAYED, _T.SYSTEM_DECAY),
    ((_C.REARMING,), _C.DECAYED, _T.REARM_NOT_APPLIED),
    ((_C.RELEASED, _C.REARMING), _C.BRAKING, _T.EB_FLAG),
    ((_C.BRAKING,), _C.STANDSTILL, _T.STANDSTILL),
    ((_C.STANDSTILL,), _C.REARMING, _T.REARM_CONFIRMED),
    ((_C.REARMING,), _C.RELEASED, _T.REARM_VERIFIED),
)
TASK_C_ETCS_TRANSITIONS = _rows(
    Fsm.TASK_C_ETCS,
    ((_E.INSERTED,), _E.ISOLATING, _T.ISOLATION_CONFIRMED),
    ((_E.ISOLATING,), _E.ISOLATED, _T.ISOLATION_VERIFIED),
    ((_E.ISOLATING,), _E.FAILED, _T.ISOLATION_NOT_ACTUATED),
    ((_E.ISOLATED,), _E.INSERTING, _T.INSERTION_CONFIRMED),
    ((_E.INSERTING,), _E.INSERTED, _T.INSERTION_VERIFIED),
    ((_E.INSERTING,), _E.FAILED, _T.INSERTION_NOT_ACTUATED),
)

ALL_TABLES: dict[Fsm, tuple[TransitionRule[StrEnum], ...]] = {
    Fsm.TASK_A: TASK_A_TRANSITIONS,
    Fsm.TASK_B: TASK_B_TRANSITIONS,
    Fsm.TASK_C_BRAKE: TASK_C_BRAKE_TRANSITIONS,
    Fsm.TASK_C_ETCS: TASK_C_ETCS_TRANSITIONS,
}
"""Every table, by FSM."""


def select_rule(
    table: tuple[TransitionRule[S], ...], state: S, triggers: Set[Trigger]
) -> TransitionRule[S] | None:
    """The first row leaving ``state`` whose trigger is in ``triggers``, or None."""
    for rule in table:
        if state in rule.sources and rule.trigger in triggers:
            return rule
    return None


@dataclass(frozen=True, slots=True, kw_only=True)
class FsmTransition:
    """A transition taken: when, in which FSM, by which row, from and to."""

    time_s: float
    fsm: Fsm
    number: int
    source: str
    target: str
    trigger: Trigger


class StateMachine(Generic[S]):
    """One FSM (or region): its state, its table and the record of the transitions taken."""

    def __init__(self, table: tuple[TransitionRule[S], ...], initial: S) -> None:
        self.table = table
        self.state = initial
        self.transitions: list[FsmTransition] = []

    def fire(self, triggers: Set[Trigger], now_s: float) -> TransitionRule[S] | None:
        """Take the first row that leaves the state on one of ``triggers``; return it."""
        if not triggers:
            return None
        rule = select_rule(self.table, self.state, triggers)
        if rule is not None:
            self.transitions.append(
                FsmTransition(
                    time_s=now_s,
                    fsm=rule.fsm,
                    number=rule.number,
                    source=self.state.value,
                    target=rule.target.value,
                    trigger=rule.trigger,
                )
            )
            self.state = rule.target
        return rule


@dataclass(frozen=True, kw_only=True)
class FsmCoverage:
    """Transition coverage of one FSM: rows, and (row, source) pairs."""

    fsm: Fsm
    rows_total: int
    rows_missing: tuple[str, ...]
    pairs_total: int
    pairs_missing: tuple[str, ...]

    @property
    def rows_covered(self) -> float:
        return 1.0 - len(self.rows_missing) / self.rows_total

    @property
    def pairs_covered(self) -> float:
        return 1.0 - len(self.pairs_missing) / self.pairs_total


def transition_coverage(taken: Iterable[FsmTransition]) -> dict[Fsm, FsmCoverage]:
    """How many rows, and (row, source) pairs, of each table the transitions ``taken`` visit."""
    records = list(taken)
    rows = {(t.fsm, t.number) for t in records}
    pairs = {(t.fsm, t.number, t.source) for t in records}
    result: dict[Fsm, FsmCoverage] = {}
    for fsm, table in ALL_TABLES.items():
        all_pairs = [(rule, source) for rule in table for source in sorted(rule.sources)]
        result[fsm] = FsmCoverage(
            fsm=fsm,
            rows_total=len(table),
            rows_missing=tuple(r.label for r in table if (fsm, r.number) not in rows),
            pairs_total=len(all_pairs),
            pairs_missing=tuple(
                f"{rule.label} from {source.value}"
                for rule, source in all_pairs
                if (fsm, rule.number, source.value) not in pairs
            ),
        )
    return result
