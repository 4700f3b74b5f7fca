"""Builders shared by the VC tests: requests, responses, statuses, quick scenarios."""

from __future__ import annotations

from typing import Any

from deploy.bench.vc_runner import ScenarioResult, run_scenario
from deploy.bench.vc_scenarios import Hazard, HazardKind, OutcomeClass, Scenario
from onboard.vc import (
    SECTIONS,
    AtoObResponse,
    AtoObStatus,
    Section,
    SectionRequest,
    SectionResponse,
    SupervisionStatus,
    TaskBState,
    VcRequest,
    expected_response_number,
)

__all__ = ["quick", "request", "response_to", "supervision"]


def request(
    sent_s: float = 0.0,
    *,
    numbers: dict[Section, int] | None = None,
    flags: dict[Section, bool] | None = None,
) -> VcRequest:
    """A request; vitality and EB release enabled unless ``flags`` says otherwise."""
    numbers = numbers or {}
    enabled = {Section.ATO_VITALITY: True, Section.EB_RELEASE_CONFIRMATION: True, **(flags or {})}
    return VcRequest(
        sent_s=sent_s,
        sections=tuple(SectionRequest(numbers.get(s, 0), enabled.get(s, False)) for s in SECTIONS),
        estimated_speed_mps=0.0,
        estimated_position_m=0.0,
        last_balise_header=None,
    )


def response_to(
    sent: VcRequest,
    *,
    answers: dict[Section, bool] | None = None,
    status: AtoObStatus = AtoObStatus.OK,
    modulo: int = 256,
) -> AtoObResponse:
    """The valid response to ``sent``: numbers as expected, vitality answered."""
    answers = {Section.ATO_VITALITY: True, **(answers or {})}
    return AtoObResponse(
        sections=tuple(
            SectionResponse(
                expected_response_number(sent.section(s), modulo),
                answers.get(s, False) and sent.section(s).request_flag,
            )
            for s in SECTIONS
        ),
        status=status,
    )


_BASE = SupervisionStatus(
    time_s=0.0,
    state=TaskBState.MONITORING,
    eb_flag=False,
    eb_conditions=frozenset(),
    live_conditions=frozenset(),
    system_decay=False,
    decay_reasons=(),
    standstill=False,
    odometry_efficient=True,
    speed_mps=0.0,
    position_m=0.0,
    etcs_isolated=False,
    eb_released=False,
    vigilance_confirmed_number=None,
    etcs_isolation_confirmed_number=None,
    etcs_insertion_confirmed_number=None,
    eb_rearm_confirmed_number=None,
    last_balise_header=None,
)


def supervision(time_s: float, **changes: Any) -> SupervisionStatus:
    """A Task B status at ``time_s``: monitoring, moving, nothing confirmed, unless changed."""
    return _BASE._replace(time_s=time_s, **changes)


def quick(
    key: str, duration_s: float, *, hazard_at_s: float | None = None, **fields: object
) -> ScenarioResult:
    """Run an ad-hoc scenario (expected class irrelevant: tests check the result)."""
    hazard = Hazard(kind=HazardKind.AT, at_s=hazard_at_s) if hazard_at_s is not None else None
    scenario = Scenario(
        key=key,
        title=key,
        expected=OutcomeClass.NONE,
        duration_s=duration_s,
        hazard=hazard,
        **fields,  # type: ignore[arg-type]
    )
    return run_scenario(scenario)
