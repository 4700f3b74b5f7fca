"""The three FSMs' transition tables, the engine, and the coverage measure."""

from __future__ import annotations

from enum import StrEnum

import pytest

from onboard.vc import (
    ALL_TABLES,
    BrakeState,
    EtcsState,
    Fsm,
    FsmTransition,
    StateMachine,
    TaskAState,
    TaskBState,
    TransitionRule,
    Trigger,
    select_rule,
    transition_coverage,
)

ROWS = [
    (rule, source)
    for table in ALL_TABLES.values()
    for rule in table
    for source in sorted(rule.sources)
]


def test_tables_are_numbered_in_order() -> None:
    for table in ALL_TABLES.values():
        assert [rule.number for rule in table] == list(range(1, len(table) + 1))
    assert {fsm: len(t) for fsm, t in ALL_TABLES.items()} == {
        Fsm.TASK_A: 5,
        Fsm.TASK_B: 3,
        Fsm.TASK_C_BRAKE: 6,
        Fsm.TASK_C_ETCS: 6,
    }


@pytest.mark.parametrize(("rule", "source"), ROWS, ids=[f"{r.label}-{s.value}" for r, s in ROWS])
def test_each_row_is_selected_from_each_of_its_sources(
    rule: TransitionRule[StrEnum], source: StrEnum
) -> None:
    assert select_rule(ALL_TABLES[rule.fsm], source, {rule.trigger}) is rule


def test_decay_comes_first_and_decayed_states_are_final() -> None:
    for fsm in (Fsm.TASK_A, Fsm.TASK_B, Fsm.TASK_C_BRAKE):
        assert ALL_TABLES[fsm][0].target.value == "decayed"
    for state in (TaskAState.DECAYED, TaskBState.DECAYED, BrakeState.DECAYED, EtcsState.FAILED):
        table = next(t for t in ALL_TABLES.values() if state in {r.target for r in t})
        assert select_rule(table, state, set(Trigger)) is None


def test_the_decay_row_wins_over_any_other_trigger() -> None:
    table = ALL_TABLES[Fsm.TASK_C_BRAKE]
    rule = select_rule(table, BrakeState.REARMING, set(Trigger))
    assert rule is not None
    assert rule.trigger is Trigger.SYSTEM_DECAY


def test_a_state_machine_records_what_it_takes() -> None:
    machine = StateMachine(ALL_TABLES[Fsm.TASK_B], TaskBState.MONITORING)
    assert machine.fire({Trigger.STANDSTILL}, 0.1) is None
    assert machine.fire({Trigger.EB_CONDITION}, 0.2) is not None
    assert machine.state is TaskBState.EB_DEMANDED
    assert machine.transitions == [
        FsmTransition(
            time_s=0.2,
            fsm=Fsm.TASK_B,
            number=2,
            source="monitoring",
            target="eb_demanded",
            trigger=Trigger.EB_CONDITION,
        )
    ]


def test_coverage_lists_what_is_missing() -> None:
    taken = [
        FsmTransition(
            time_s=0.0,
            fsm=Fsm.TASK_B,
            number=1,
            source="monitoring",
            target="decayed",
            trigger=Trigger.DECAY_CONDITION,
        )
    ]
    coverage = transition_coverage(taken)[Fsm.TASK_B]
    assert coverage.rows_missing == ("B2", "B3")
    assert coverage.pairs_missing == (
        "B1 from eb_demanded",
        "B2 from monitoring",
        "B3 from eb_demanded",
    )
    assert coverage.rows_covered == pytest.approx(1 / 3)
    assert transition_coverage([])[Fsm.TASK_A].rows_covered == 0.0
