"""The ATO-OB controller's timers, failure, GoA4 choices, outputs and determinism."""

from __future__ import annotations

import contextlib
import importlib
import math
import random
from dataclasses import replace
from typing import Any

import pytest

import onboard.ato_ob as ato_ob
from onboard.adf.supervisor import ModeRequest
from onboard.ato_ob import (
    ATO_OB_TRANSITIONS,
    AtoObController,
    AtoObInputError,
    AtoObOutput,
    AtoTransition,
    Condition,
    EtcsStatus,
    RequestRefusedError,
    Trigger,
)
from protocol.messages import AtoState, EtcsMode
from tests.onboard.ato_ob.drive import (
    DT_S,
    EOA_M,
    PERMITTED_MPS,
    SVL_M,
    Drive,
    etcs_status,
    in_state,
    inputs,
)
from tests.onboard.etcs.layouts import in_full_supervision, level_line

S = AtoState
MOVING = {"mode": EtcsMode.AD, "standstill": False, "at_stopping_point": False}
BRAKING = {"etcs": {"service_brake": True}, "standstill": False, "at_stopping_point": False}


def _engaged_between_stops() -> Drive:
    drive = in_state(S.ENGAGED)
    drive.next(**MOVING)
    return drive


# -- DE: 5 s without traction, then the full service brake -----------------------------------


def test_disengaging_follows_the_profile_for_5_s_then_brakes() -> None:
    drive = in_state(S.DISENGAGING)
    start_s = drive.controller.transitions[-1].time_s
    early = drive.at(start_s + 4.9, **BRAKING)
    assert early.state is S.DISENGAGING
    assert (early.mode_request, early.traction_allowed, early.full_service_brake) == (
        ModeRequest.AUTONOMOUS,
        False,
        False,
    )
    assert early.disengaging_remaining_s == pytest.approx(0.1, abs=1e-9)
    late = drive.at(start_s + 5.1, **BRAKING)
    assert late.state is S.DISENGAGING
    assert (late.mode_request, late.traction_allowed, late.full_service_brake) == (
        ModeRequest.OFF,
        False,
        True,
    )
    assert late.disengaging_remaining_s == 0.0
    stopped = drive.next(etcs={"service_brake": True})
    assert (stopped.state, stopped.full_service_brake) == (S.NOT_AVAILABLE, False)
    assert drive.controller.transitions[-1].trigger is Trigger.BRAKED_TO_STANDSTILL


def test_disengaging_recovers_to_engaged_within_the_5_s() -> None:
    drive = in_state(S.DISENGAGING)
    start_s = drive.controller.transitions[-1].time_s
    assert drive.at(start_s + 4.9, standstill=False).state is S.ENGAGED
    assert drive.controller.transitions[-1].trigger is Trigger.CONDITIONS_RECOVERED
    out = drive.controller.output
    assert (out.automatic_driving_requested, out.traction_allowed) == (True, True)
    # ETCS is in FS; it gets the AD request and enters AD at its next cycle.
    assert drive.next(**MOVING).state is S.ENGAGED
    assert drive.at(drive.now_s + 10.0, **MOVING).state is S.ENGAGED


def test_no_recovery_once_the_service_brake_is_applied() -> None:
    drive = in_state(S.DISENGAGING)
    start_s = drive.controller.transitions[-1].time_s
    out = drive.at(start_s + 5.1, standstill=False)
    assert (out.state, out.full_service_brake) == (S.DISENGAGING, True)


def test_etcs_must_enter_automatic_driving_once_engaged() -> None:
    drive = in_state(S.READY)
    drive.controller.engage(drive.now_s)
    engaged_s = drive.now_s
    assert drive.at(engaged_s + 2.0, standstill=False).state is S.ENGAGED
    out = drive.at(engaged_s + 2.1, standstill=False)
    assert out.state is S.DISENGAGING
    assert drive.controller.transitions[-1].reason == "lost: etcs_mode"


def test_etcs_leaving_automatic_driving_disengages_at_once() -> None:
    drive = _engaged_between_stops()
    assert drive.next(standstill=False, at_stopping_point=False).state is S.DISENGAGING


# -- FA: the ETCS-OB link, internal faults, reset -----------------------------------------------


def test_a_lost_etcs_link_fails_and_only_a_reset_leaves_failure() -> None:
    drive = _engaged_between_stops()
    last_s = drive.now_s
    assert drive.at(last_s + 1.0, link=False, **MOVING).state is S.ENGAGED
    failed = drive.at(last_s + 1.1, link=False, **MOVING)
    assert failed.state is S.FAILURE
    assert (failed.mode_request, failed.traction_allowed) == (ModeRequest.OFF, False)
    assert (failed.full_service_brake, failed.failure_warning) == (True, True)
    assert failed.unavailable_reasons == (Condition.ETCS_LINK,)
    assert drive.controller.transitions[-1].trigger is Trigger.ETCS_LINK_LOST
    with pytest.raises(RequestRefusedError, match="etcs_link"):
        drive.controller.reset(drive.now_s)
    back = drive.at(last_s + 1.2, **MOVING)
    assert (back.state, back.unavailable_reasons) == (S.FAILURE, ())
    assert drive.at(last_s + 6.0).failure_warning
    assert not drive.at(last_s + 6.2).failure_warning
    drive.controller.reset(drive.now_s)
    assert drive.state is S.CONFIGURATION
    assert drive.controller.output.full_service_brake is False
    assert drive.next(dwell_elapsed=False).state is S.NOT_AVAILABLE
    assert drive.next(dwell_elapsed=False).state is S.AVAILABLE
    assert drive.next().state is S.READY
    assert drive.next().state is S.READY  # no automatic engagement after a failure


def test_a_link_that_never_comes_up_fails_after_the_timeout() -> None:
    drive = Drive()
    assert drive.at(0.0, link=False).state is S.CONFIGURATION
    waiting = drive.at(1.0, link=False)
    assert (waiting.state, waiting.unavailable_reasons) == (S.CONFIGURATION, (Condition.ETCS_LINK,))
    assert drive.at(1.1, link=False).state is S.FAILURE


def test_reset_is_refused_while_the_internal_fault_remains() -> None:
    drive = in_state(S.FAILURE)
    with pytest.raises(RequestRefusedError, match="no_internal_fault"):
        drive.controller.reset(drive.now_s)
    drive.next()
    drive.controller.reset(drive.now_s)
    assert drive.state is S.CONFIGURATION


def test_configuration_waits_for_the_track_data_version() -> None:
    drive = in_state(S.CONFIGURATION)
    out = drive.next(track_data_version_matches=False)
    assert (out.state, out.unavailable_reasons) == (
        S.CONFIGURATION,
        (Condition.TRACK_DATA_VERSION,),
    )


# -- GoA4: the journey continues after the dwell; the session-loss fallback ----------------------


def test_the_unmanned_train_continues_after_the_dwell_time() -> None:
    drive = _engaged_between_stops()
    stopped = drive.next(mode=EtcsMode.AD, dwell_elapsed=False)
    assert stopped.state is S.AVAILABLE
    assert stopped.continue_after_dwell
    assert (stopped.mode_request, stopped.automatic_driving_requested) == (ModeRequest.OFF, False)
    assert stopped.not_ready_reasons == (Condition.DWELL_TIME_ELAPSED,)
    for _ in range(20):
        assert drive.next(dwell_elapsed=False).state is S.AVAILABLE
    assert drive.next().state is S.READY
    again = drive.next()
    assert again.state is S.ENGAGED
    assert not again.continue_after_dwell
    assert drive.controller.transitions[-1].trigger is Trigger.AUTOMATIC_REENGAGEMENT


@pytest.mark.parametrize("operator", ["disengage", "remote_driving"])
def test_the_operator_can_keep_the_train_at_the_stop(operator: str) -> None:
    drive = _engaged_between_stops()
    drive.next(mode=EtcsMode.AD, dwell_elapsed=False)
    remote = operator == "remote_driving"
    if not remote:
        drive.controller.disengage(drive.now_s)
    assert not drive.next(dwell_elapsed=False, remote_driving_selected=remote).continue_after_dwell
    assert drive.next(remote_driving_selected=remote).state is S.READY
    assert drive.next(remote_driving_selected=remote).state is S.READY


def test_engaging_at_a_stopping_point_is_no_arrival() -> None:
    drive = in_state(S.READY)
    drive.controller.engage(drive.now_s)
    assert drive.next(mode=EtcsMode.AD).state is S.ENGAGED
    assert drive.next(mode=EtcsMode.AD).state is S.ENGAGED
    drive.next(**MOVING)
    assert drive.next(mode=EtcsMode.AD).state is S.AVAILABLE


def test_stopping_short_of_a_stopping_point_stays_engaged() -> None:
    drive = _engaged_between_stops()
    assert drive.next(mode=EtcsMode.AD, at_stopping_point=False).state is S.ENGAGED


def test_the_end_of_journey_ends_engagement_at_standstill_only() -> None:
    drive = _engaged_between_stops()
    assert drive.next(end_of_journey_reached=True, **MOVING).state is S.ENGAGED
    end = drive.next(mode=EtcsMode.AD, end_of_journey_reached=True)
    assert end.state is S.NOT_AVAILABLE
    assert not end.continue_after_dwell
    assert end.unavailable_reasons == (Condition.END_OF_JOURNEY_NOT_REACHED,)


def test_a_lost_session_stops_the_train_at_the_next_stopping_point() -> None:
    drive = _engaged_between_stops()
    lost = drive.next(trackside_session_alive=False, **MOVING)
    assert lost.state is S.ENGAGED
    assert (lost.stop_at_next_stopping_point, lost.traction_allowed) == (True, True)
    assert lost.mode_request is ModeRequest.AUTONOMOUS
    assert lost.not_ready_reasons == (Condition.TRACKSIDE_SESSION,)
    # Standing (at a signal, say) when the session comes back: the fallback holds.
    at_signal = drive.next(mode=EtcsMode.AD, at_stopping_point=False)
    assert (at_signal.state, at_signal.stop_at_next_stopping_point) == (S.ENGAGED, True)
    # Back while running (a trackside restart): the fallback is cancelled, the journey goes on.
    back = drive.next(**MOVING)
    assert (back.state, back.stop_at_next_stopping_point) == (S.ENGAGED, False)
    assert drive.next(trackside_session_alive=False, **MOVING).stop_at_next_stopping_point
    stopped = drive.next(mode=EtcsMode.AD, trackside_session_alive=False)
    assert stopped.state is S.AVAILABLE
    assert not (stopped.stop_at_next_stopping_point)
    assert not (stopped.continue_after_dwell)
    assert drive.controller.transitions[-1].trigger is Trigger.FALLBACK_STOP_COMPLETED
    assert drive.next(trackside_session_alive=False).state is S.AVAILABLE
    assert drive.next().state is S.READY
    assert drive.next().state is S.READY  # the remote driver decides when it leaves
    drive.controller.engage(drive.now_s)
    assert drive.state is S.ENGAGED


def test_a_lost_session_while_ready_withdraws_readiness() -> None:
    drive = in_state(S.READY)
    out = drive.next(trackside_session_alive=False)
    assert (out.state, out.not_ready_reasons) == (S.AVAILABLE, (Condition.TRACKSIDE_SESSION,))


# -- outputs ----------------------------------------------------------------------------------


@pytest.mark.parametrize("state", [S.NOT_AVAILABLE, S.AVAILABLE, S.READY], ids=str)
def test_the_remote_driver_drives_when_not_engaged(state: AtoState) -> None:
    drive = in_state(state)
    dwell = state is S.READY
    out = drive.next(remote_driving_selected=True, dwell_elapsed=dwell, mode=EtcsMode.SR)
    assert (out.mode_request, out.traction_allowed) == (ModeRequest.REMOTE, True)
    cut = drive.next(remote_driving_selected=True, etcs={"traction_cut": True})
    assert (cut.mode_request, cut.traction_allowed) == (ModeRequest.REMOTE, False)


def test_remote_driving_is_ignored_while_engaged() -> None:
    drive = _engaged_between_stops()
    out = drive.next(remote_driving_selected=True, **MOVING)
    assert (out.state, out.mode_request) == (S.ENGAGED, ModeRequest.AUTONOMOUS)


def test_the_etcs_limits_pass_through_to_the_adf() -> None:
    drive = Drive()
    first = drive.at(0.0, link=False)
    assert (first.permitted_speed_mps, first.end_of_authority_distance_m) == (0.0, None)
    out = drive.next()
    assert (out.permitted_speed_mps, out.end_of_authority_distance_m) == (PERMITTED_MPS, EOA_M)
    assert out.supervised_location_distance_m == SVL_M
    later = drive.next(etcs={"permitted_speed_mps": 8.0, "end_of_authority_distance_m": 42.0})
    assert (later.permitted_speed_mps, later.end_of_authority_distance_m) == (8.0, 42.0)


def test_entering_full_supervision_displayed_is_not_yet_available() -> None:
    drive = in_state(S.NOT_AVAILABLE)
    out = drive.next(etcs={"entering_full_supervision_displayed": True})
    assert (out.state, out.unavailable_reasons) == (S.NOT_AVAILABLE, (Condition.ETCS_MODE,))


def test_the_initial_output_is_np_and_holds_the_vehicle() -> None:
    out = AtoObController(start_s=3.0).output
    assert (out.time_s, out.state, out.mode_request) == (3.0, S.NP, ModeRequest.OFF)
    assert not (out.traction_allowed)
    assert not (out.full_service_brake)


# -- determinism and invariants ---------------------------------------------------------------


def _random_run(seed: int, steps: int = 1500) -> tuple[list[AtoObOutput], list[AtoTransition]]:
    rng = random.Random(seed)
    controller = AtoObController()
    outputs = []
    flags = (
        "journey_profile_valid",
        "dwell_elapsed",
        "standstill",
        "at_stopping_point",
        "trackside_session_alive",
        "movement_authority_allows_departure",
    )
    for k in range(steps):
        now_s = round(k * DT_S, 9)
        changes = {name: rng.random() > 0.1 for name in flags}
        etcs = {"service_brake": rng.random() < 0.03, "received_s": now_s - rng.random() * 1.2}
        mode = rng.choice([EtcsMode.FS, EtcsMode.AD, EtcsMode.AD, EtcsMode.SR])
        step_inputs = inputs(
            now_s,
            mode=mode,
            etcs=etcs,
            internal_fault=rng.random() < 0.01,
            end_of_journey_reached=rng.random() < 0.02,
            **changes,
        )
        out = controller.step(now_s, step_inputs)
        outputs.append(out)
        request = rng.choice(
            [None, None, None, controller.engage, controller.disengage, controller.reset]
        )
        if request is not None:
            with contextlib.suppress(RequestRefusedError):
                request(now_s)
    return outputs, controller.transitions


def test_the_same_inputs_give_the_same_run() -> None:
    first, second = _random_run(7), _random_run(7)
    assert first == second
    assert len(first[1]) > 50


def test_random_runs_keep_the_invariants() -> None:
    outputs, transitions = _random_run(11)
    visited = {t.target for t in transitions}
    assert visited == set(AtoState) - {S.NP}
    for out in outputs:
        assert not (out.traction_allowed and out.full_service_brake)
        assert out.full_service_brake <= (out.state in (S.DISENGAGING, S.FAILURE))
        assert out.automatic_driving_requested is (out.state is S.ENGAGED)
        assert out.stop_at_next_stopping_point <= (out.state is S.ENGAGED)
    rows = {
        (source, rule.target, rule.trigger)
        for rule in ATO_OB_TRANSITIONS
        for source in rule.sources
    }
    for previous, transition in zip(transitions, transitions[1:], strict=False):
        assert (transition.source, transition.target, transition.trigger) in rows
        assert transition.source is previous.target
        assert transition.time_s >= previous.time_s


# -- with the ETCS onboard ----------------------------------------------------------------------


def test_engagement_takes_etcs_from_fs_to_ad_and_back() -> None:
    etcs = in_full_supervision(level_line(), position_m=100.0, end_of_authority_m=5_000.0)
    controller = AtoObController()
    now_s = 0.0

    def cycle(**changes: Any) -> AtoObOutput:
        status = EtcsStatus.from_output(etcs.step(now_s, 100.0, 0.0))
        out = controller.step(now_s, replace(inputs(now_s, **changes), etcs=status))
        etcs.request_automatic_driving(out.automatic_driving_requested, now_s)
        return out

    for _ in range(4):
        now_s += DT_S
        cycle()
    assert (controller.state, etcs.mode) == (S.READY, EtcsMode.FS)
    controller.engage(now_s)
    etcs.request_automatic_driving(controller.output.automatic_driving_requested, now_s)
    for _ in range(30):
        now_s += DT_S
        out = cycle(at_stopping_point=False)
    assert (out.state, etcs.mode) == (S.ENGAGED, EtcsMode.AD)
    assert out.end_of_authority_distance_m == pytest.approx(4_900.0, abs=1.0)
    controller.disengage(now_s)
    etcs.request_automatic_driving(controller.output.automatic_driving_requested, now_s)
    assert etcs.mode is EtcsMode.FS


# -- bad calls and the package's surface ----------------------------------------------------


def test_bad_calls_raise_input_errors() -> None:
    controller = AtoObController()
    controller.step(1.0, inputs(1.0))
    with pytest.raises(AtoObInputError):
        controller.step(0.5, inputs(0.5))
    with pytest.raises(AtoObInputError):
        controller.step(math.nan, inputs(1.0))
    with pytest.raises(AtoObInputError):
        controller.step(2.0, inputs(2.0, etcs={"received_s": 2.5}))
    with pytest.raises(AtoObInputError):
        etcs_status(0.0, permitted_speed_mps=-1.0)
    with pytest.raises(AtoObInputError):
        etcs_status(0.0, end_of_authority_distance_m=math.inf)
    with pytest.raises(AtoObInputError):
        AtoObController(disengaging_s=0.0)
    with pytest.raises(ValueError, match="before 2.0 s"):  # the input errors are ValueErrors
        controller.engage(0.0)


def test_all_is_complete() -> None:
    assert all(hasattr(ato_ob, name) for name in ato_ob.__all__)
    for name in ("conditions", "controller", "transitions", "_exceptions"):
        module = importlib.import_module(f"onboard.ato_ob.{name}")
        assert all(hasattr(module, item) for item in module.__all__)
    private = importlib.import_module("onboard.ato_ob._exceptions")
    assert set(private.__all__) <= set(ato_ob.__all__)
