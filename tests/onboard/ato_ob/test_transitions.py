"""The transition table: each row through select_rule, then through the controller."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from onboard.adf.supervisor import ModeRequest
from onboard.ato_ob import (
    ATO_OB_TRANSITIONS,
    AtoObOutput,
    Condition,
    RequestRefusedError,
    TransitionRule,
    Trigger,
)
from onboard.ato_ob.transitions import REQUEST_TRIGGERS, select_rule
from protocol.messages import AtoState, EtcsMode
from tests.onboard.ato_ob.drive import DT_S, Drive, in_state

S = AtoState
ROWS = [(rule, source) for rule in ATO_OB_TRANSITIONS for source in sorted(rule.sources)]
MOVING = {"mode": EtcsMode.AD, "standstill": False, "at_stopping_point": False}


def test_rows_are_numbered_in_priority_order() -> None:
    assert [rule.number for rule in ATO_OB_TRANSITIONS] == list(range(1, 19))


@pytest.mark.parametrize(
    ("rule", "source"), ROWS, ids=[f"{r.number}-{s}-{r.target}-{r.trigger}" for r, s in ROWS]
)
def test_each_row_is_selected_from_each_of_its_sources(
    rule: TransitionRule, source: AtoState
) -> None:
    assert select_rule(source, {rule.trigger}) is rule


def test_no_row_leaves_a_state_it_does_not_name() -> None:
    for rule in ATO_OB_TRANSITIONS:
        for state in set(AtoState) - rule.sources:
            chosen = select_rule(state, {rule.trigger})
            assert chosen is None or state in chosen.sources


def test_faults_come_first_and_every_state_but_np_and_fa_can_fail() -> None:
    assert select_rule(S.ENGAGED, set(Trigger)) is ATO_OB_TRANSITIONS[0]
    failing = {s for r in ATO_OB_TRANSITIONS if r.target is S.FAILURE for s in r.sources}
    assert failing == set(AtoState) - {S.NP, S.FAILURE}


# -- each row through the controller ---------------------------------------------------------


def _link_lost(drive: Drive) -> None:
    changes = MOVING if drive.state in (S.ENGAGED, S.DISENGAGING) else {}
    drive.at(drive.now_s + 1.5, link=False, **changes)


def _fallback_stop(drive: Drive) -> None:
    out = drive.next(trackside_session_alive=False, **MOVING)
    assert (out.state, out.stop_at_next_stopping_point) == (S.ENGAGED, True)
    drive.next(mode=EtcsMode.AD, trackside_session_alive=False)


def _reset(drive: Drive) -> None:
    drive.next()
    assert drive.state is S.FAILURE
    drive.controller.reset(drive.now_s)


def _braked_to_standstill(drive: Drive) -> None:
    brake = {"etcs": {"service_brake": True}, "standstill": False, "at_stopping_point": False}
    out = drive.at(drive.now_s + 5.1, **brake)
    assert (out.state, out.full_service_brake) == (S.DISENGAGING, True)
    drive.next(etcs={"service_brake": True}, at_stopping_point=False)


def _automatic_reengagement(drive: Drive) -> None:
    drive.next(mode=EtcsMode.AD, dwell_elapsed=False)  # EG → AV at the stop
    assert drive.controller.output.continue_after_dwell
    drive.next(dwell_elapsed=False)
    assert drive.state is S.AVAILABLE
    drive.next()  # AV → RE
    assert drive.state is S.READY
    drive.next()


ACTIONS: dict[Trigger, Callable[[Drive], object]] = {
    Trigger.ETCS_LINK_LOST: _link_lost,
    Trigger.INTERNAL_FAULT: lambda d: d.next(internal_fault=True),
    Trigger.POWER_ON: lambda d: d.at(0.0),
    Trigger.RESET: _reset,
    Trigger.CONFIGURED: lambda d: d.next(dwell_elapsed=False),
    Trigger.DISENGAGE_REQUESTED: lambda d: d.controller.disengage(d.now_s),
    Trigger.END_OF_JOURNEY: lambda d: d.next(mode=EtcsMode.AD, end_of_journey_reached=True),
    Trigger.FALLBACK_STOP_COMPLETED: _fallback_stop,
    Trigger.STOPPED_AT_STOPPING_POINT: lambda d: d.next(mode=EtcsMode.AD, dwell_elapsed=False),
    Trigger.NOT_OPERATIONAL: lambda d: d.next(
        etcs={"service_brake": True}, journey_profile_valid=False, standstill=False
    ),
    Trigger.CONDITIONS_RECOVERED: lambda d: d.at(d.now_s + 1.0, standstill=False),
    Trigger.BRAKED_TO_STANDSTILL: _braked_to_standstill,
    Trigger.NOT_ENGAGEABLE: lambda d: d.next(dwell_elapsed=False),
    Trigger.OPERATIONAL: lambda d: d.next(dwell_elapsed=False),
    Trigger.ENGAGEABLE: lambda d: d.next(),
    Trigger.ENGAGE_REQUESTED: lambda d: d.controller.engage(d.now_s),
    Trigger.AUTOMATIC_REENGAGEMENT: _automatic_reengagement,
}

SETUPS: dict[Trigger, Callable[[AtoState], Drive]] = {
    Trigger.AUTOMATIC_REENGAGEMENT: lambda _: _engaged_between_stops(),
    Trigger.END_OF_JOURNEY: lambda _: _engaged_between_stops(),
    Trigger.FALLBACK_STOP_COMPLETED: lambda _: _engaged_between_stops(),
    Trigger.STOPPED_AT_STOPPING_POINT: lambda _: _engaged_between_stops(),
}


def _engaged_between_stops() -> Drive:
    drive = in_state(S.ENGAGED)
    drive.next(**MOVING)
    return drive


def _expected_outputs(out: AtoObOutput) -> None:
    """What every state shows when the operator does not drive (no remote driving)."""
    mode, traction, brake = {
        S.NP: (ModeRequest.OFF, False, False),
        S.CONFIGURATION: (ModeRequest.OFF, False, False),
        S.NOT_AVAILABLE: (ModeRequest.OFF, False, False),
        S.AVAILABLE: (ModeRequest.OFF, False, False),
        S.READY: (ModeRequest.OFF, False, False),
        S.ENGAGED: (ModeRequest.AUTONOMOUS, True, False),
        S.DISENGAGING: (ModeRequest.AUTONOMOUS, False, False),
        S.FAILURE: (ModeRequest.OFF, False, True),
    }[out.state]
    assert (out.mode_request, out.traction_allowed, out.full_service_brake) == (
        mode,
        traction,
        brake,
    )
    assert out.automatic_driving_requested is (out.state is S.ENGAGED)
    assert out.failure_warning is (out.state is S.FAILURE)
    assert not hasattr(out, "emergency_brake")  # the ATO-OB never commands the EB (§2.1)


@pytest.mark.parametrize(
    ("rule", "source"), ROWS, ids=[f"{r.number}-{s}-{r.target}-{r.trigger}" for r, s in ROWS]
)
def test_each_row_is_taken_by_the_controller(rule: TransitionRule, source: AtoState) -> None:
    drive = SETUPS.get(rule.trigger, in_state)(source)
    before = len(drive.controller.transitions)
    ACTIONS[rule.trigger](drive)
    taken = drive.controller.transitions[before:]
    assert [(t.source, t.target, t.trigger) for t in taken][-1] == (
        source,
        rule.target,
        rule.trigger,
    )
    assert drive.state is rule.target
    assert taken[-1].time_s == drive.now_s
    assert taken[-1].reason
    _expected_outputs(drive.controller.output)


def test_the_not_operational_reason_names_the_lost_conditions() -> None:
    drive = in_state(S.AVAILABLE)
    drive.next(journey_profile_valid=False, localisation_valid=False)
    assert drive.controller.transitions[-1].reason == "lost: journey_profile_valid, localised"
    assert drive.controller.output.unavailable_reasons == (
        Condition.JOURNEY_PROFILE_VALID,
        Condition.LOCALISED,
    )


def test_request_triggers_never_come_from_a_cycle() -> None:
    """Cycles in every state with all inputs nominal or failing take no operator's row."""
    for state in AtoState:
        drive = in_state(state)
        for changes in ({}, {"internal_fault": True}, {"standstill": False}):
            before = len(drive.controller.transitions)
            drive.at(drive.now_s + DT_S, **changes)
            for transition in drive.controller.transitions[before:]:
                assert transition.trigger not in REQUEST_TRIGGERS


@pytest.mark.parametrize("state", [s for s in AtoState if s is not S.READY])
def test_engage_is_refused_outside_ready(state: AtoState) -> None:
    drive = in_state(state)
    before = list(drive.controller.transitions)
    with pytest.raises(RequestRefusedError, match=f"in {state}, not RE"):
        drive.controller.engage(drive.now_s)
    assert drive.state is state
    assert drive.controller.transitions == before


def test_a_refused_engage_says_what_is_missing() -> None:
    drive = in_state(S.AVAILABLE)
    with pytest.raises(RequestRefusedError, match="dwell_time_elapsed"):
        drive.controller.engage(drive.now_s)


@pytest.mark.parametrize("state", [S.NP, S.CONFIGURATION, S.NOT_AVAILABLE, S.FAILURE], ids=str)
def test_disengage_is_refused_with_nothing_engaged(state: AtoState) -> None:
    drive = in_state(state)
    with pytest.raises(RequestRefusedError, match="nothing engaged"):
        drive.controller.disengage(drive.now_s)
    assert drive.state is state


@pytest.mark.parametrize("state", [s for s in AtoState if s is not S.FAILURE])
def test_reset_is_refused_outside_failure(state: AtoState) -> None:
    drive = in_state(state)
    with pytest.raises(RequestRefusedError, match="not FA"):
        drive.controller.reset(drive.now_s)
    assert drive.state is state
