"""The six EB conditions, the decay conditions and the window edge, end to end in lockstep."""

from __future__ import annotations

import pytest

from deploy.bench.vc_responder import OperatorAction, OperatorActionKind
from deploy.bench.vc_runner import ScenarioResult
from deploy.bench.vc_scenarios import OutcomeClass, SpeedTarget
from onboard.vc import (
    DecayReason,
    EbCondition,
    FsmTransition,
    LinkDirection,
    LinkFault,
    LinkFaultKind,
    VcEventKind,
)
from tests.onboard.vc.helpers import quick

pytestmark = pytest.mark.scenario


def _conditions(result: ScenarioResult) -> list[int]:
    return [int(e.detail.split()[0]) for e in result.events if e.kind is VcEventKind.EB_CONDITION]


@pytest.mark.parametrize(
    ("key", "condition"),
    [
        ("A", EbCondition.OPERATOR_REQUEST),
        ("B", EbCondition.ATO_OB_FAIL),
        ("C", EbCondition.RESPONSE_NOT_VALID),
        ("E", EbCondition.RESPONSE_NOT_VALID),
        ("D", EbCondition.CONFIRMATION_TIMEOUT),
        ("N", EbCondition.CONFIRMATION_TIMEOUT),
        ("M", EbCondition.ODOMETRY_NOT_EFFICIENT),
        ("M-silent", EbCondition.ODOMETRY_NOT_EFFICIENT),
        ("M-noisy", EbCondition.ODOMETRY_NOT_EFFICIENT),
        ("L", EbCondition.OVERSPEED_ETCS_ISOLATED),
    ],
)
def test_each_eb_condition_commands_the_eb(
    catalogue_results: dict[str, ScenarioResult], key: str, condition: EbCondition
) -> None:
    result = catalogue_results[key]
    assert _conditions(result)[0] == condition
    assert result.eb_command_s is not None
    assert result.evidence_s is not None
    # Task C acts in the cycle Task B raises the flag: within one 2 ms period of the evidence.
    assert 0.0 <= result.eb_command_s - result.evidence_s <= 0.002 + 1e-9


@pytest.mark.parametrize(
    ("key", "reason"),
    [
        ("B", DecayReason.ATO_OB_FAIL),
        ("C", DecayReason.RESPONSE_NOT_VALID),
        ("D", DecayReason.VIGILANCE_TIMEOUT),
        ("N", DecayReason.VITALITY_TIMEOUT),
        ("F", DecayReason.ETCS_ISOLATION_NOT_ACTUATED),
        ("F-insertion", DecayReason.ETCS_INSERTION_NOT_ACTUATED),
        ("G", DecayReason.EB_REARM_NOT_APPLIED),
    ],
)
def test_each_decay_condition(
    catalogue_results: dict[str, ScenarioResult], key: str, reason: DecayReason
) -> None:
    result = catalogue_results[key]
    assert result.decay_reasons[0] == reason
    assert result.decay_s is not None
    assert result.evidence_to_decay_s is not None
    assert result.evidence_to_decay_s <= 0.002 + 1e-9


@pytest.mark.parametrize("key", ["A", "L", "M", "M-silent", "M-noisy"])
def test_recoverable_conditions_never_decay(
    catalogue_results: dict[str, ScenarioResult], key: str
) -> None:
    result = catalogue_results[key]
    assert result.decay_s is None
    assert not result.decay_reasons
    assert result.rearmed_s is not None
    assert result.eb_command_s is not None
    assert result.rearmed_s > result.eb_command_s


@pytest.mark.parametrize(("round_trip_ms", "brakes"), [(43, False), (44, False), (45, True)])
def test_the_exchange_window_edge(round_trip_ms: int, brakes: bool) -> None:
    """43 ms (and 44 ms, the limit itself) pass; 45 ms brakes and decays."""
    delay = LinkFault(
        direction=LinkDirection.RESPONSE,
        kind=LinkFaultKind.DELAY,
        start_s=2.0,
        delay_s=round_trip_ms / 1000,
    )
    result = quick(
        f"round trip {round_trip_ms} ms", 3.0, hazard_at_s=2.0, link_delay_s=0.0, faults=(delay,)
    )
    assert (result.decay_s is not None) is brakes
    if brakes:
        assert result.decay_reasons[0] is DecayReason.VITALITY_TIMEOUT
        # The request of 2.000 s is due by 2.044 s; the tick after (2.046 s) commands the EB.
        assert result.decay_s == pytest.approx(2.046)
        assert result.eb_command_s == pytest.approx(2.046)


def _first(result: ScenarioResult, number: int, fsm: str) -> FsmTransition:
    return next(t for t in result.transitions if t.fsm.value == fsm and t.number == number)


def test_rearm_waits_for_standstill_though_confirmed_while_braking() -> None:
    result = quick(
        "confirm while braking",
        18.0,
        hazard_at_s=9.003,
        auto_confirm_rearm=False,
        driver=(SpeedTarget(from_s=2.0, speed_kmh=25.0),),
        operator=(
            OperatorAction(at_s=0.0, kind=OperatorActionKind.CONFIRM_REARM),
            OperatorAction(at_s=9.003, kind=OperatorActionKind.REQUEST_EB),
            OperatorAction(at_s=10.0, kind=OperatorActionKind.CONFIRM_REARM),
        ),
    )
    assert result.outcome is OutcomeClass.EB_SAFE_RECOVERY
    standstill = [t for t in result.transitions if t.fsm.value == "C.brake" and t.number == 4]
    rearms = [t for t in result.transitions if t.fsm.value == "C.brake" and t.number == 5]
    assert len(standstill) == 2
    assert len(rearms) == 2
    # The confirmation given at 10 s (braking) is used only after the standstill.
    assert standstill[1].time_s > 15.0
    assert rearms[1].time_s > standstill[1].time_s
    assert result.rearmed_s is not None
    assert result.rearmed_s > rearms[1].time_s
