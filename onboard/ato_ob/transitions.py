"""The ATO-OB states' transitions (SUBSET-125 §9; DOMAIN.md §2.1), as an explicit table.

Rows are in priority order: from a state, the first row whose trigger holds is taken, one row per
cycle. ``*`` stands for CO, NA, AV, RE, EG and DE. Triggers marked (request) come from the
operator's calls, never from the cycle's inputs.

===  ==========  ==  =============================  ==============================================
no.  from        to  trigger                        meaning
===  ==========  ==  =============================  ==============================================
1    \\*         FA  etcs_link_lost                 no ETCS-OB output within the link timeout
2    \\*         FA  internal_fault                 the ATO-OB reports a fault of its own
3    NP          CO  power_on                       the first cycle
4    FA          CO  reset (request)                the operator's reset, the cause cleared
5    CO          NA  configured                     link up, track data version, self-test
6    EG DE       NA  disengage_requested (request)  the remote driver's "ATO Disengage"
7    EG          NA  end_of_journey                 at standstill at the End of Journey
8    EG          AV  fallback_stop_completed        session lost: stopped at the next stopping
                                                    point; the journey waits for the operator
9    EG          AV  stopped_at_stopping_point      at standstill at a stopping point after a
                                                    run; the holding brake applied
10   EG          DE  not_operational                an operational condition lost (ETCS left AD)
11   DE          EG  conditions_recovered           within the 5 s, the conditions hold again
12   DE          NA  braked_to_standstill           the 5 s passed; full service brake to a stop
13   AV RE       NA  not_operational                an operational condition lost
14   RE          AV  not_engageable                 an engagement condition lost
15   NA          AV  operational                    the operational conditions hold
16   AV          RE  engageable                     and the engagement conditions hold
17   RE          EG  engage_requested (request)     the remote driver's "ATO Engage"
18   RE          EG  automatic_reengagement         GoA4: after a nominal stop, no driver needed
===  ==========  ==  =============================  ==============================================

:func:`select_rule` picks the row; :class:`onboard.ato_ob.AtoObController` works out which
triggers hold and what each transition does to the outputs.
"""

from __future__ import annotations

from collections.abc import Set
from dataclasses import dataclass
from enum import StrEnum

from protocol.messages import AtoState

__all__ = ["ATO_OB_TRANSITIONS", "REQUEST_TRIGGERS", "TransitionRule", "Trigger", "select_rule"]


class Trigger(StrEnum):
    """Why a transition is taken; the controller evaluates each every cycle."""

    ETCS_LINK_LOST = "etcs_link_lost"
    INTERNAL_FAULT = "internal_fault"
    POWER_ON = "power_on"
    RESET = "reset"
    CONFIGURED = "configured"
    DISENGAGE_REQUESTED = "disengage_requested"
    END_OF_JOURNEY = "end_of_journey"
    FALLBACK_STOP_COMPLETED = "fallback_stop_completed"
    STOPPED_AT_STOPPING_POINT = "stopped_at_stopping_point"
    NOT_OPERATIONAL = "not_operational"
    CONDITIONS_RECOVERED = "conditions_recovered"
    BRAKED_TO_STANDSTILL = "braked_to_standstill"
    NOT_ENGAGEABLE = "not_engageable"
    OPERATIONAL = "operational"
    ENGAGEABLE = "engageable"
    ENGAGE_REQUESTED = "engage_requested"
    AUTOMATIC_REENGAGEMENT = "automatic_reengagement"


REQUEST_TRIGGERS = frozenset({Trigger.RESET, Trigger.DISENGAGE_REQUESTED, Trigger.ENGAGE_REQUESTED})
"""Triggers that only the operator's calls raise."""


@dataclass(frozen=True, kw_only=True)
class TransitionRule:
    """One row of the transition table."""

    number: int
    sources: frozenset[AtoState]
    target: AtoState
    trigger: Trigger


def _states(*states: AtoState) -> frozenset[AtoState]:
    return frozenset(states)


_S = AtoState
_T = Trigger
_RUNNING = _states(
    _S.CONFIGURATION, _S.NOT_AVAILABLE, _S.AVAILABLE, _S.READY, _S.ENGAGED, _S.DISENGAGING
)

ATO_OB_TRANSITIONS: tuple[TransitionRule, ...] = (
    TransitionRule(number=1, sources=_RUNNING, target=_S.FAILURE, trigger=_T.ETCS_LINK_LOST),
    TransitionRule(number=2, sources=_RUNNING, target=_S.FAILURE, trigger=_T.INTERNAL_FAULT),
    TransitionRule(number=3, sources=_states(_S.NP), target=_S.CONFIGURATION, trigger=_T.POWER_ON),
    TransitionRule(
        number=4, sources=_states(_S.FAILURE), target=_S.CONFIGURATION, trigger=_T.RESET
    ),
    TransitionRule(
        number=5, sources=_states(_S.CONFIGURATION), target=_S.NOT_AVAILABLE, trigger=_T.CONFIGURED
    ),
    TransitionRule(
        number=6,
        sources=_states(_S.ENGAGED, _S.DISENGAGING),
        target=_S.NOT_AVAILABLE,
        trigger=_T.DISENGAGE_REQUESTED,
    ),
    TransitionRule(
        number=7, sources=_states(_S.ENGAGED), target=_S.NOT_AVAILABLE, trigger=_T.END_OF_JOURNEY
    ),
    TransitionRule(
        number=8,
        sources=_states(_S.ENGAGED),
        target=_S.AVAILABLE,
        trigger=_T.FALLBACK_STOP_COMPLETED,
    ),
    TransitionRule(
        number=9,
        sources=_states(_S.ENGAGED),
        target=_S.AVAILABLE,
        trigger=_T.STOPPED_AT_STOPPING_POINT,
    ),
    TransitionRule(
        number=10, sources=_states(_S.ENGAGED), target=_S.DISENGAGING, trigger=_T.NOT_OPERATIONAL
    ),
    TransitionRule(
        number=11,
        sources=_states(_S.DISENGAGING),
        target=_S.ENGAGED,
        trigger=_T.CONDITIONS_RECOVERED,
    ),
    TransitionRule(
        number=12,
        sources=_states(_S.DISENGAGING),
        target=_S.NOT_AVAILABLE,
        trigger=_T.BRAKED_TO_STANDSTILL,
    ),
    TransitionRule(
        number=13,
        sources=_states(_S.AVAILABLE, _S.READY),
        target=_S.NOT_AVAILABLE,
        trigger=_T.NOT_OPERATIONAL,
    ),
    TransitionRule(
        number=14, sources=_states(_S.READY), target=_S.AVAILABLE, trigger=_T.NOT_ENGAGEABLE
    ),
    TransitionRule(
        number=15, sources=_states(_S.NOT_AVAILABLE), target=_S.AVAILABLE, trigger=_T.OPERATIONAL
    ),
    TransitionRule(
        number=16, sources=_states(_S.AVAILABLE), target=_S.READY, trigger=_T.ENGAGEABLE
    ),
    TransitionRule(
        number=17, sources=_states(_S.READY), target=_S.ENGAGED, trigger=_T.ENGAGE_REQUESTED
    ),
    TransitionRule(
        number=18, sources=_states(_S.READY), target=_S.ENGAGED, trigger=_T.AUTOMATIC_REENGAGEMENT
    ),
)
"""The transition table (see the module's docstring), in priority order."""


def select_rule(state: AtoState, triggers: Set[Trigger]) -> TransitionRule | None:
    """The first row leaving ``state`` whose trigger is in ``triggers``, or None."""
    for rule in ATO_OB_TRANSITIONS:
        if state in rule.sources and rule.trigger in triggers:
            return rule
    return None
