"""Task B's checks of the ATO-OB's responses: validity, status, the 40 + 4 ms window."""

from __future__ import annotations

from dataclasses import dataclass

import pytest
from hypothesis import given
from hypothesis import strategies as st

from onboard.etcs.balises import TelegramHeader
from onboard.vc import (
    SECTIONS,
    ActuationStatus,
    AtoObResponse,
    AtoObStatus,
    BrakeState,
    DecayReason,
    Delivery,
    EbCondition,
    EtcsState,
    FaultyLink,
    LinkDirection,
    Mailbox,
    MessageQueue,
    Section,
    SectionResponse,
    SupervisionStatus,
    TaskB,
    TaskBState,
    VcConfig,
    VcRequest,
)
from onboard.vc.hardware import TachometerFrame
from tests.onboard.vc.helpers import request, response_to


@dataclass
class Rig:
    """Task B alone, with its inputs in the test's hands (the link has no delay)."""

    task: TaskB
    sent: MessageQueue[VcRequest]
    responses: FaultyLink[AtoObResponse]
    actuation: Mailbox[ActuationStatus]

    def exchange(
        self, sent: VcRequest, response: AtoObResponse | None, read_s: float
    ) -> SupervisionStatus:
        self.sent.put(sent)
        if response is not None:
            self.responses.send(response, sent.sent_s)
        return self.task.step(read_s)


def _rig() -> Rig:
    sent = MessageQueue[VcRequest]()
    responses = FaultyLink[AtoObResponse](LinkDirection.RESPONSE, delay_s=0.0)
    actuation = Mailbox[ActuationStatus]()
    task = TaskB(
        VcConfig(),
        response_link=responses,
        requests_sent=sent,
        tachometer_frames=MessageQueue[Delivery[TachometerFrame]](),
        balise_telegrams=MessageQueue[Delivery[TelegramHeader]](),
        read_eb_released=lambda _t: False,
        read_etcs_inserted=lambda _t: True,
        actuation=actuation,
    )
    return Rig(task, sent, responses, actuation)


def test_a_valid_response_raises_nothing() -> None:
    rig = _rig()
    sent = request(0.0, numbers={Section.ATO_VITALITY: 1, Section.EB_RELEASE_CONFIRMATION: 1})
    status = rig.exchange(sent, response_to(sent), 0.002)
    assert (status.state, status.eb_flag, status.live_conditions) == (
        TaskBState.MONITORING,
        False,
        frozenset(),
    )


@pytest.mark.parametrize(
    ("section", "returned"),
    [
        (Section.ATO_VITALITY, 3),  # incremented by two
        (Section.EB_RELEASE_CONFIRMATION, 1),  # enabled, not incremented
        (Section.EB_RELEASE_CONFIRMATION, 0),  # decremented
        (Section.EB_REARM_CONFIRMATION, 1),  # not enabled, incremented
        (Section.OPERATOR_VIGILANCE, 5),  # not enabled, changed
    ],
)
def test_invalid_sequence_increments_raise_eb_and_decay(section: Section, returned: int) -> None:
    rig = _rig()
    sent = request(0.0, numbers={Section.ATO_VITALITY: 1, Section.EB_RELEASE_CONFIRMATION: 1})
    response = response_to(sent).with_section(section, SectionResponse(returned, False))
    status = rig.exchange(sent, response, 0.002)
    assert status.state is TaskBState.DECAYED
    assert status.eb_flag
    assert status.system_decay
    assert EbCondition.RESPONSE_NOT_VALID in status.live_conditions
    assert status.decay_reasons == (DecayReason.RESPONSE_NOT_VALID,)


def test_a_replayed_response_is_not_valid() -> None:
    rig = _rig()
    first = request(0.0, numbers={Section.ATO_VITALITY: 1})
    assert not rig.exchange(first, response_to(first), 0.002).eb_flag
    second = request(0.04, numbers={Section.ATO_VITALITY: 2})
    status = rig.exchange(second, response_to(first), 0.042)
    assert status.decay_reasons == (DecayReason.RESPONSE_NOT_VALID,)


def test_numbers_wrap_after_255() -> None:
    rig = _rig()
    sent = request(0.0, numbers={Section.ATO_VITALITY: 255, Section.EB_RELEASE_CONFIRMATION: 255})
    response = response_to(sent)
    assert response.section(Section.ATO_VITALITY).sequence_number == 0
    assert not rig.exchange(sent, response, 0.002).eb_flag


def test_status_fail_raises_eb_and_decay() -> None:
    rig = _rig()
    sent = request(0.0, numbers={Section.ATO_VITALITY: 1})
    status = rig.exchange(sent, response_to(sent, status=AtoObStatus.FAIL), 0.002)
    assert status.system_decay
    assert status.decay_reasons == (DecayReason.ATO_OB_FAIL,)
    assert EbCondition.ATO_OB_FAIL in status.eb_conditions


def test_the_operators_eb_request_raises_the_flag_without_decay() -> None:
    rig = _rig()
    sent = request(0.0, numbers={Section.ATO_VITALITY: 1})
    status = rig.exchange(
        sent, response_to(sent, answers={Section.EB_RELEASE_CONFIRMATION: True}), 0.002
    )
    assert status.state is TaskBState.EB_DEMANDED
    assert not status.system_decay
    assert status.eb_conditions == {EbCondition.OPERATOR_REQUEST}


@pytest.mark.parametrize(("read_ms", "late"), [(44, False), (46, True)])
def test_the_40_plus_4_ms_window(read_ms: int, late: bool) -> None:
    """A response read at 44 ms passes; one first read at 46 ms (the next tick) is too late."""
    rig = _rig()
    sent = request(1.0, numbers={Section.ATO_VITALITY: 1})
    rig.sent.put(sent)
    rig.task.step(1.042)
    rig.responses.send(response_to(sent), 1.0 + read_ms / 1000 - 0.001)
    status = rig.task.step(1.0 + read_ms / 1000)
    assert status.system_decay is late
    if late:
        assert status.decay_reasons == (DecayReason.VITALITY_TIMEOUT,)


def test_a_response_never_read_times_out_at_the_first_tick_past_44_ms() -> None:
    rig = _rig()
    sent = request(1.0, numbers={Section.ATO_VITALITY: 1})
    assert not rig.exchange(sent, None, 1.044).eb_flag
    status = rig.task.step(1.046)
    assert status.decay_reasons == (DecayReason.VITALITY_TIMEOUT,)
    assert rig.task.events[0].evidence_s == pytest.approx(1.044)


def test_confirmations_count_only_for_the_current_request() -> None:
    rig = _rig()
    flags = {Section.EB_REARM_CONFIRMATION: True}
    sent = request(
        0.0, numbers={Section.ATO_VITALITY: 1, Section.EB_REARM_CONFIRMATION: 4}, flags=flags
    )
    status = rig.exchange(
        sent, response_to(sent, answers={Section.EB_REARM_CONFIRMATION: True}), 0.002
    )
    assert status.eb_rearm_confirmed_number == 4
    dropped = request(0.04, numbers={Section.ATO_VITALITY: 2, Section.EB_REARM_CONFIRMATION: 4})
    assert rig.exchange(dropped, response_to(dropped), 0.042).eb_rearm_confirmed_number is None


def test_hazard_cleared_only_at_standstill_with_the_eb_held() -> None:
    rig = _rig()
    sent = request(0.0, numbers={Section.ATO_VITALITY: 1})
    rig.exchange(sent, response_to(sent, answers={Section.EB_RELEASE_CONFIRMATION: True}), 0.002)
    braking = ActuationStatus(
        time_s=0.002,
        brake_state=BrakeState.BRAKING,
        etcs_state=EtcsState.INSERTED,
        valves_energised=False,
        relay_inserted_commanded=True,
        system_decay=False,
        decay_reasons=(),
        consumed_rearm_number=None,
    )
    rig.actuation.post(braking)
    assert rig.task.step(0.004).state is TaskBState.EB_DEMANDED


_NUMBERS = st.integers(min_value=0, max_value=255)


@given(
    numbers=st.lists(_NUMBERS, min_size=6, max_size=6),
    flags=st.lists(st.booleans(), min_size=6, max_size=6),
    index=st.integers(min_value=0, max_value=5),
    shift=st.integers(min_value=1, max_value=255),
)
def test_exactly_the_expected_numbers_are_valid(
    numbers: list[int], flags: list[bool], index: int, shift: int
) -> None:
    sent = request(
        0.0,
        numbers=dict(zip(SECTIONS, numbers, strict=True)),
        flags=dict(zip(SECTIONS, [True, *flags[1:]], strict=True)),
    )
    valid = response_to(sent)
    assert not _rig().exchange(sent, valid, 0.002).system_decay
    section = SECTIONS[index]
    moved = (valid.section(section).sequence_number + shift) % 256
    invalid = valid.with_section(section, SectionResponse(moved, False))
    assert _rig().exchange(sent, invalid, 0.002).decay_reasons == (DecayReason.RESPONSE_NOT_VALID,)
