"""The request/response messages and the fault-injectable link between the VC and the ATO-OB."""

from __future__ import annotations

import math

import pytest

from onboard.vc import (
    SECTIONS,
    AtoObResponse,
    AtoObStatus,
    FaultyLink,
    LinkDirection,
    LinkFault,
    LinkFaultKind,
    Section,
    SectionRequest,
    SectionResponse,
    VcInputError,
    VcRequest,
    corrupt_response,
    expected_response_number,
)
from tests.onboard.vc.helpers import request, response_to


def test_six_sections_in_the_seeds_order() -> None:
    assert [s.value for s in SECTIONS] == [
        "ato_vitality",
        "operator_vigilance",
        "eb_release_confirmation",
        "etcs_insertion_confirmation",
        "etcs_isolation_confirmation",
        "eb_rearm_confirmation",
    ]


def test_expected_number_increments_only_enabled_sections_and_wraps() -> None:
    assert expected_response_number(SectionRequest(7, True), 256) == 8
    assert expected_response_number(SectionRequest(255, True), 256) == 0
    assert expected_response_number(SectionRequest(7, False), 256) == 7


def test_messages_need_six_sections_and_numbers_in_range() -> None:
    with pytest.raises(VcInputError):
        VcRequest(
            sent_s=0.0,
            sections=(SectionRequest(0, True),) * 5,
            estimated_speed_mps=None,
            estimated_position_m=None,
            last_balise_header=None,
        )
    with pytest.raises(VcInputError):
        AtoObResponse(sections=(SectionResponse(-1, False),) * 6, status=AtoObStatus.OK)


def test_response_sections_by_name() -> None:
    sent = request(
        numbers={Section.OPERATOR_VIGILANCE: 4}, flags={Section.OPERATOR_VIGILANCE: True}
    )
    response = response_to(sent, answers={Section.OPERATOR_VIGILANCE: True})
    assert response.section(Section.OPERATOR_VIGILANCE) == SectionResponse(5, True)
    assert response.section(Section.ETCS_ISOLATION_CONFIRMATION) == SectionResponse(0, False)


# -- the link ---------------------------------------------------------------------------------


def _link(*faults: LinkFault, delay_s: float = 0.001) -> FaultyLink[str]:
    return FaultyLink(LinkDirection.RESPONSE, delay_s=delay_s, faults=faults)


def test_messages_arrive_after_the_delay_in_order() -> None:
    link = _link()
    link.send("first", 0.0)
    link.send("second", 0.0005)
    assert link.receive(0.0009) == ()
    arrived = link.receive(0.002)
    assert [d.message for d in arrived] == ["first", "second"]
    assert [d.arrived_s for d in arrived] == pytest.approx([0.001, 0.0015])
    assert link.receive(0.01) == ()


def test_drop_and_delay_apply_to_messages_sent_in_their_window() -> None:
    drop = LinkFault(
        direction=LinkDirection.RESPONSE, kind=LinkFaultKind.DROP, start_s=1.0, end_s=2.0
    )
    slow = LinkFault(
        direction=LinkDirection.RESPONSE, kind=LinkFaultKind.DELAY, start_s=3.0, delay_s=0.04
    )
    link = _link(drop, slow)
    for t in (0.5, 1.5, 2.5, 3.5):
        link.send(f"at {t}", t)
    arrived = link.receive(10.0)
    assert [(d.message, round(d.arrived_s, 6)) for d in arrived] == [
        ("at 0.5", 0.501),
        ("at 2.5", 2.501),
        ("at 3.5", 3.541),
    ]
    assert link.dropped == 1


def test_freeze_repeats_the_last_message_before_the_window() -> None:
    freeze = LinkFault(direction=LinkDirection.RESPONSE, kind=LinkFaultKind.FREEZE, start_s=1.0)
    link = _link(freeze)
    link.send("fresh", 0.5)
    link.send("new", 1.5)
    link.send("newer", 2.5)
    assert [d.message for d in link.receive(10.0)] == ["fresh", "fresh", "fresh"]


def test_freeze_with_nothing_sent_before_loses_the_messages() -> None:
    link = _link(
        LinkFault(direction=LinkDirection.RESPONSE, kind=LinkFaultKind.FREEZE, start_s=0.0)
    )
    link.send("lost", 0.5)
    assert link.receive(10.0) == ()


def test_corrupt_moves_one_section_number_or_drops_without_a_corrupter() -> None:
    fault = LinkFault(
        direction=LinkDirection.RESPONSE,
        kind=LinkFaultKind.CORRUPT,
        start_s=0.0,
        section=Section.EB_RELEASE_CONFIRMATION,
    )
    link: FaultyLink[AtoObResponse] = FaultyLink(
        LinkDirection.RESPONSE, faults=(fault,), corrupt=corrupt_response
    )
    valid = response_to(request(numbers={Section.EB_RELEASE_CONFIRMATION: 254}))
    link.send(valid, 0.0)
    (arrived,) = link.receive(1.0)
    assert arrived.message.section(Section.EB_RELEASE_CONFIRMATION).sequence_number == 1
    assert arrived.message.section(Section.ATO_VITALITY) == valid.section(Section.ATO_VITALITY)
    plain = _link(fault)
    plain.send("x", 0.0)
    assert plain.receive(1.0) == ()
    assert plain.dropped == 1


def test_a_direction_ignores_the_other_directions_faults() -> None:
    link = FaultyLink[str](
        LinkDirection.REQUEST,
        faults=(LinkFault(direction=LinkDirection.RESPONSE, kind=LinkFaultKind.DROP, start_s=0.0),),
    )
    link.send("kept", 0.0)
    assert len(link.receive(1.0)) == 1


@pytest.mark.parametrize(("start_s", "end_s"), [(1.0, 1.0), (2.0, 1.0), (math.nan, 3.0)])
def test_fault_windows_must_make_sense(start_s: float, end_s: float) -> None:
    with pytest.raises(VcInputError):
        LinkFault(
            direction=LinkDirection.REQUEST, kind=LinkFaultKind.DROP, start_s=start_s, end_s=end_s
        )
