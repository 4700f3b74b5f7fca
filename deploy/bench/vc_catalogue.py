"""The VC scenario catalogue: 36 scenarios after seeds 001 and 004 (DOMAIN.md §7.2).

The seeds tested 36 scenarios, 23 hazardous: 5 EB with safe recovery, 10 EB then System Decay,
8 System Decay at standstill. Their Table 1 is not in our copy, so the list is ours: the seeds'
letters A, B, C, D, E, F, G, L, M, N where the text describes them, and the rest chosen to cover
each fault mode of the link (delay, drop, corrupt, freeze), of the ATO-OB, of the tachometer
board (frozen, noisy, silent), of the relay and of the brake pipe, the nominal paths, and every
transition of the three FSMs. Each scenario starts at power-up: EB applied, rearm confirmed by
the operator once the VC sees standstill (about 1.5 s), then the remote driver's targets.

Faults on a message exchange start 3 ms after a request's instant (9.003 s): just after the
ATO-OB has answered, the worst phase for the VC.
"""

from __future__ import annotations

from deploy.bench.vc_responder import (
    OperatorAction,
    OperatorActionKind,
    ResponderFault,
    ResponderFaultKind,
)
from deploy.bench.vc_scenarios import Hazard, HazardKind, OutcomeClass, Scenario, SpeedTarget
from onboard.vc.hardware import (
    PipeFault,
    RelayFault,
    TachometerFault,
    TachometerFaultMode,
)
from onboard.vc.link import LinkDirection, LinkFault, LinkFaultKind
from onboard.vc.messages import Section

__all__ = ["CATALOGUE", "scenario"]

_O = OutcomeClass
_K = OperatorActionKind
_R = ResponderFaultKind
_T = TachometerFaultMode
WORST_PHASE_S = 9.003
"""Just after the ATO-OB's answer to the request of 9.000 s."""


def _at(time_s: float) -> Hazard:
    return Hazard(kind=HazardKind.AT, at_s=time_s)


def _drive(*targets: tuple[float, float]) -> tuple[SpeedTarget, ...]:
    return tuple(SpeedTarget(from_s=t, speed_kmh=v) for t, v in targets)


def _operator(*actions: tuple[float, OperatorActionKind]) -> tuple[OperatorAction, ...]:
    return tuple(OperatorAction(at_s=t, kind=k) for t, k in actions)


def _response(
    kind: LinkFaultKind,
    start_s: float,
    *,
    delay_s: float = 0.0,
    section: Section = Section.ATO_VITALITY,
) -> LinkFault:
    return LinkFault(
        direction=LinkDirection.RESPONSE,
        kind=kind,
        start_s=start_s,
        delay_s=delay_s,
        section=section,
    )


RUN_25 = _drive((2.0, 25.0))
"""Depart at 2 s for 25 km/h (about 23 km/h at 9 s)."""
ISOLATE = _operator((0.0, _K.REQUEST_ETCS_ISOLATION))
"""The operator has ETCS isolated at the first standstill."""

_EB_SAFE_RECOVERY = (
    Scenario(
        key="A",
        seed_letter="A",
        title="operator requests the EB while running; rearm at standstill",
        expected=_O.EB_SAFE_RECOVERY,
        duration_s=19.0,
        hazard=_at(WORST_PHASE_S),
        driver=_drive((2.0, 25.0), (WORST_PHASE_S, 0.0), (12.0, 10.0)),
        operator=_operator((WORST_PHASE_S, _K.REQUEST_EB)),
    ),
    Scenario(
        key="L",
        seed_letter="L",
        title="ETCS isolated, the driver exceeds 30 km/h; rearm, resume below it",
        expected=_O.EB_SAFE_RECOVERY,
        duration_s=24.0,
        hazard=Hazard(kind=HazardKind.OVERSPEED),
        driver=_drive((2.0, 35.0), (14.0, 20.0)),
        operator=ISOLATE,
    ),
    Scenario(
        key="M",
        seed_letter="M",
        title="ETCS isolated, tachometer board frozen for 0.5 s while running",
        expected=_O.EB_SAFE_RECOVERY,
        duration_s=20.0,
        hazard=_at(9.01),
        driver=RUN_25,
        operator=ISOLATE,
        faults=(TachometerFault(mode=_T.FROZEN, start_s=9.01, end_s=9.5),),
    ),
    Scenario(
        key="M-silent",
        title="ETCS isolated, tachometer board silent for 1 s while running",
        expected=_O.EB_SAFE_RECOVERY,
        duration_s=20.0,
        hazard=_at(9.01),
        driver=RUN_25,
        operator=ISOLATE,
        faults=(TachometerFault(mode=_T.SILENT, start_s=9.01, end_s=10.0),),
    ),
    Scenario(
        key="M-noisy",
        title="ETCS isolated, noisy tachometer channel; noise again during the rearm",
        expected=_O.EB_SAFE_RECOVERY,
        duration_s=22.0,
        hazard=_at(9.01),
        driver=RUN_25,
        operator=ISOLATE,
        faults=(
            TachometerFault(mode=_T.NOISY, start_s=9.01, end_s=9.4),
            TachometerFault(mode=_T.NOISY, start_s=17.3, end_s=17.45),
        ),
    ),
)

_EB_THEN_DECAY = (
    Scenario(
        key="B",
        seed_letter="B",
        title="ATO-OB reports FAIL while running",
        expected=_O.EB_THEN_DECAY,
        duration_s=11.0,
        hazard=_at(WORST_PHASE_S),
        driver=RUN_25,
        faults=(ResponderFault(kind=_R.STATUS_FAIL, start_s=WORST_PHASE_S),),
    ),
    Scenario(
        key="C",
        seed_letter="C",
        title="response not valid: ATO Vitality number wrongly incremented",
        expected=_O.EB_THEN_DECAY,
        duration_s=11.0,
        hazard=_at(WORST_PHASE_S),
        driver=RUN_25,
        faults=(ResponderFault(kind=_R.WRONG_INCREMENT, start_s=WORST_PHASE_S),),
    ),
    Scenario(
        key="D",
        seed_letter="D",
        title="operator absent: vigilance not confirmed within the time limit",
        expected=_O.EB_THEN_DECAY,
        duration_s=14.0,
        hazard=_at(12.0),
        driver=RUN_25,
        operator=_operator((8.0, _K.LEAVE)),
    ),
    Scenario(
        key="E",
        seed_letter="E",
        title="not-valid vigilance answer (its number wrongly incremented)",
        expected=_O.EB_THEN_DECAY,
        duration_s=12.0,
        hazard=_at(10.0),
        driver=RUN_25,
        faults=(
            ResponderFault(
                kind=_R.WRONG_INCREMENT, start_s=10.0, section=Section.OPERATOR_VIGILANCE
            ),
        ),
    ),
    Scenario(
        key="N",
        seed_letter="N",
        title="ATO-OB stops answering: vitality (and vigilance) timeout",
        expected=_O.EB_THEN_DECAY,
        duration_s=11.0,
        hazard=_at(WORST_PHASE_S),
        driver=RUN_25,
        faults=(ResponderFault(kind=_R.SILENT, start_s=WORST_PHASE_S),),
    ),
    Scenario(
        key="window-45ms",
        title="round trip 45 ms: beyond the 40 + 4 ms exchange window",
        expected=_O.EB_THEN_DECAY,
        duration_s=11.0,
        hazard=_at(9.0),
        driver=RUN_25,
        link_delay_s=0.0,
        faults=(_response(LinkFaultKind.DELAY, 9.0, delay_s=0.045),),
    ),
    Scenario(
        key="link-freeze",
        title="the link replays the last response (frozen)",
        expected=_O.EB_THEN_DECAY,
        duration_s=11.0,
        hazard=_at(WORST_PHASE_S),
        driver=RUN_25,
        faults=(_response(LinkFaultKind.FREEZE, WORST_PHASE_S),),
    ),
    Scenario(
        key="link-corrupt",
        title="the link corrupts the EB Release Confirmation number",
        expected=_O.EB_THEN_DECAY,
        duration_s=11.0,
        hazard=_at(WORST_PHASE_S),
        driver=RUN_25,
        faults=(
            _response(
                LinkFaultKind.CORRUPT, WORST_PHASE_S, section=Section.EB_RELEASE_CONFIRMATION
            ),
        ),
    ),
    Scenario(
        key="unsolicited-increment",
        title="ATO-OB increments the EB Rearm number though not asked",
        expected=_O.EB_THEN_DECAY,
        duration_s=11.0,
        hazard=_at(WORST_PHASE_S),
        driver=RUN_25,
        faults=(
            ResponderFault(
                kind=_R.UNSOLICITED_INCREMENT,
                start_s=WORST_PHASE_S,
                section=Section.EB_REARM_CONFIRMATION,
            ),
        ),
    ),
    Scenario(
        key="A-then-B",
        title="operator EB while running, then ATO-OB FAIL while braking",
        expected=_O.EB_THEN_DECAY,
        duration_s=13.0,
        hazard=_at(WORST_PHASE_S),
        driver=_drive((2.0, 25.0), (WORST_PHASE_S, 0.0)),
        operator=_operator((WORST_PHASE_S, _K.REQUEST_EB)),
        faults=(ResponderFault(kind=_R.STATUS_FAIL, start_s=11.0),),
    ),
)

_DECAY_AT_STANDSTILL = (
    Scenario(
        key="F",
        seed_letter="F",
        title="ETCS isolation not actuated by the relay",
        expected=_O.DECAY_AT_STANDSTILL,
        duration_s=5.0,
        hazard=Hazard(kind=HazardKind.RELAY_COMMAND),
        operator=_operator((3.0, _K.REQUEST_ETCS_ISOLATION)),
        faults=(RelayFault(start_s=0.0),),
    ),
    Scenario(
        key="F-insertion",
        title="ETCS insertion not actuated by the relay",
        expected=_O.DECAY_AT_STANDSTILL,
        duration_s=5.0,
        hazard=Hazard(kind=HazardKind.RELAY_COMMAND),
        etcs_inserted_at_start=False,
        operator=_operator((3.0, _K.REQUEST_ETCS_INSERTION)),
        faults=(RelayFault(start_s=0.0),),
    ),
    Scenario(
        key="G",
        seed_letter="G",
        title="EB rearm not applied: the brake pipe does not recharge",
        expected=_O.DECAY_AT_STANDSTILL,
        duration_s=4.0,
        hazard=Hazard(kind=HazardKind.REARM_COMMAND),
        faults=(PipeFault(start_s=0.0),),
    ),
    Scenario(
        key="rearm-not-valid",
        title="not-valid answer to the EB Rearm Confirmation (seed 001's F)",
        expected=_O.DECAY_AT_STANDSTILL,
        duration_s=2.0,
        hazard=_at(0.24),
        faults=(
            ResponderFault(
                kind=_R.WRONG_INCREMENT, start_s=0.0, section=Section.EB_REARM_CONFIRMATION
            ),
        ),
    ),
    Scenario(
        key="B-while-rearming",
        title="ATO-OB reports FAIL while the VC rearms after power-up",
        expected=_O.DECAY_AT_STANDSTILL,
        duration_s=3.0,
        hazard=_at(1.003),
        faults=(ResponderFault(kind=_R.STATUS_FAIL, start_s=1.003),),
    ),
    Scenario(
        key="isolation-not-valid",
        title="not-valid answer to the ETCS Isolation Confirmation at standstill",
        expected=_O.DECAY_AT_STANDSTILL,
        duration_s=7.0,
        hazard=_at(5.003),
        faults=(
            ResponderFault(
                kind=_R.WRONG_INCREMENT,
                start_s=5.003,
                section=Section.ETCS_ISOLATION_CONFIRMATION,
            ),
        ),
    ),
    Scenario(
        key="D-at-standstill",
        title="operator absent at standstill: vigilance time limit",
        expected=_O.DECAY_AT_STANDSTILL,
        duration_s=9.0,
        hazard=_at(7.0),
        operator=_operator((3.0, _K.LEAVE)),
    ),
    Scenario(
        key="link-drop",
        title="the link loses the requests at standstill",
        expected=_O.DECAY_AT_STANDSTILL,
        duration_s=7.0,
        hazard=_at(5.0),
        faults=(LinkFault(direction=LinkDirection.REQUEST, kind=LinkFaultKind.DROP, start_s=5.0),),
    ),
)

_NONE = (
    Scenario(
        key="power-up",
        title="power-up: standstill, rearm confirmed, EB released",
        expected=_O.NONE,
        duration_s=3.0,
    ),
    Scenario(
        key="nominal-run",
        title="run at 40 km/h with ETCS inserted, vigilance confirmed four times",
        expected=_O.NONE,
        duration_s=16.0,
        driver=_drive((2.0, 40.0)),
    ),
    Scenario(
        key="isolated-run",
        title="ETCS isolated at standstill, remote driving at 25 km/h",
        expected=_O.NONE,
        duration_s=12.0,
        driver=RUN_25,
        operator=ISOLATE,
    ),
    Scenario(
        key="isolate-insert",
        title="ETCS isolated then inserted again at standstill",
        expected=_O.NONE,
        duration_s=4.0,
        operator=_operator((0.0, _K.REQUEST_ETCS_ISOLATION), (2.0, _K.REQUEST_ETCS_INSERTION)),
    ),
    Scenario(
        key="window-43ms",
        title="round trip 43 ms: inside the 40 + 4 ms exchange window",
        expected=_O.NONE,
        duration_s=6.0,
        driver=RUN_25,
        link_delay_s=0.0,
        faults=(_response(LinkFaultKind.DELAY, 3.0, delay_s=0.043),),
    ),
    Scenario(
        key="noisy-inserted",
        title="noisy tachometer with ETCS inserted: ETCS supervises, no EB",
        expected=_O.NONE,
        duration_s=11.0,
        driver=RUN_25,
        faults=(TachometerFault(mode=_T.NOISY, start_s=8.0, end_s=9.0),),
    ),
    Scenario(
        key="silent-inserted",
        title="silent tachometer with ETCS inserted",
        expected=_O.NONE,
        duration_s=11.0,
        driver=RUN_25,
        faults=(TachometerFault(mode=_T.SILENT, start_s=8.0, end_s=9.0),),
    ),
    Scenario(
        key="frozen-inserted",
        title="frozen tachometer with ETCS inserted",
        expected=_O.NONE,
        duration_s=11.0,
        driver=RUN_25,
        faults=(TachometerFault(mode=_T.FROZEN, start_s=8.0, end_s=9.0),),
    ),
    Scenario(
        key="late-vigilance",
        title="vigilance confirmed late, still within the time limit",
        expected=_O.NONE,
        duration_s=9.0,
        driver=RUN_25,
        operator=_operator((4.0, _K.LEAVE), (6.2, _K.RETURN)),
    ),
    Scenario(
        key="late-rearm",
        title="the operator confirms the power-up rearm only after 4 s",
        expected=_O.NONE,
        duration_s=6.0,
        auto_confirm_rearm=False,
        operator=_operator((4.0, _K.CONFIRM_REARM)),
    ),
    Scenario(
        key="isolated-28kmh",
        title="ETCS isolated, running steadily at 28 km/h, under the 30 km/h limit",
        expected=_O.NONE,
        duration_s=16.0,
        driver=_drive((2.0, 28.0)),
        operator=ISOLATE,
    ),
    Scenario(
        key="balise",
        title="a balise telegram's header forwarded to the ATO-OB",
        expected=_O.NONE,
        duration_s=8.0,
        driver=RUN_25,
        balise_telegrams=((6.0, 7),),
    ),
    Scenario(
        key="isolation-waits",
        title="ETCS isolation asked while running: done only after stopping",
        expected=_O.NONE,
        duration_s=14.0,
        driver=_drive((2.0, 20.0), (6.0, 0.0)),
        operator=_operator((4.0, _K.REQUEST_ETCS_ISOLATION)),
    ),
)

CATALOGUE: tuple[Scenario, ...] = _EB_SAFE_RECOVERY + _EB_THEN_DECAY + _DECAY_AT_STANDSTILL + _NONE
"""All 36 scenarios, grouped by expected class."""


def scenario(key: str) -> Scenario:
    """The catalogue's scenario named ``key``."""
    for item in CATALOGUE:
        if item.key == key:
            return item
    raise KeyError(key)
