"""ETCS modes and their transitions (SUBSET-026 §4.6; DOMAIN.md §1.6), as an explicit table.

Modes modelled: SB (stand-by), SR (staff responsible), FS (full supervision), OS (on sight),
AD (automatic driving, B4), TR (trip), PT (post trip) and IS (isolation). Each transition of
:data:`MODE_TRANSITIONS` names its source modes, its target, its condition, the levels it holds
in, the number of its condition in SUBSET-026 §4.6.3 where DOMAIN.md gives it (None otherwise,
⚠ not confirmed) and its priority (1 first, as in §4.6.2).

===  ==========================  =====  =====================================================
no.  from                        to     condition
===  ==========================  =====  =====================================================
—    every mode but IS           IS     ETCS isolated (the VC's relay)
—    IS                          SB     ETCS inserted again (⚠ SUBSET-026 goes through NP)
[12] FS OS AD                    TR     Level 1: the min-safe front end passes the EoA
[16] FS OS AD                    TR     Level 2: the min-safe front end passes the EoA
[11] FS OS AD                    TR     a balise group at or beyond the EoA read in RSM
[17] FS OS AD                    TR     linking reaction "train trip" (a linked group missed)
[20] SR FS OS AD                 TR     unconditional emergency stop
[42] SR                          TR     the SR distance passed
[7]  TR                          PT     trip acknowledged at standstill
[24] AD                          FS     SB or EB commanded
[53] AD                          FS     ATO disengaged (also [33], AD no longer requested)
[10] SB                          FS     MA + SSP + gradient, no mode profile
[32] SR                          FS     Level 1: MA + SSP + gradient, no mode profile
[31] SR PT OS                    FS     Level 2 (PT, OS: both levels): the same
—    SB SR PT FS                 OS     MA + SSP + gradient with the front end in an
                                        on-sight area
[80] FS                          AD     ATO engaged: AD requested, SSP and gradient under the
                                        whole train, no SB or EB commanded
—    SB PT                       SR     start of mission in SR (no MA)
===  ==========================  =====  =====================================================

The antenna is taken at the front end, so Level 1's "min-safe antenna" is the min-safe front
end. :func:`select_transition` picks, among the transitions whose source is the current mode,
whose level matches and whose condition holds, the one of highest priority.
"""

from __future__ import annotations

from collections.abc import Set
from dataclasses import dataclass
from enum import StrEnum

from onboard.etcs.movement_authority import EtcsLevel
from protocol.messages import EtcsMode

__all__ = [
    "MODELLED_MODES",
    "MODE_TRANSITIONS",
    "STANDSTILL_MODES",
    "SUPERVISED_MODES",
    "ModeChange",
    "ModeCondition",
    "ModeTransition",
    "select_transition",
]

MODELLED_MODES = frozenset(
    {
        EtcsMode.SB,
        EtcsMode.SR,
        EtcsMode.FS,
        EtcsMode.OS,
        EtcsMode.AD,
        EtcsMode.TR,
        EtcsMode.PT,
        EtcsMode.IS,
    }
)
SUPERVISED_MODES = frozenset({EtcsMode.FS, EtcsMode.OS, EtcsMode.AD})
"""The modes that supervise speed and distance against an MA, and take linking reactions."""
STANDSTILL_MODES = frozenset({EtcsMode.SB, EtcsMode.PT})
"""The modes that supervise standstill (roll-away protection) and start a mission."""
_BOTH_LEVELS = frozenset(EtcsLevel)


class ModeCondition(StrEnum):
    """A condition that may change the mode; the onboard evaluates each every cycle."""

    ISOLATED = "isolated"
    INSERTED = "inserted"
    END_OF_AUTHORITY_PASSED = "end_of_authority_passed"
    BALISE_GROUP_AT_END_OF_AUTHORITY = "balise_group_at_end_of_authority"
    LINKING_REACTION = "linking_reaction"
    """A linked balise group not read where expected, with Q_LINKREACTION "train trip"."""
    EMERGENCY_STOP = "emergency_stop"
    STAFF_RESPONSIBLE_DISTANCE_PASSED = "staff_responsible_distance_passed"
    TRIP_ACKNOWLEDGED = "trip_acknowledged"
    BRAKE_COMMANDED = "brake_commanded"
    AUTOMATIC_DRIVING_DISENGAGED = "automatic_driving_disengaged"
    AUTHORITY_AND_TRACK_DESCRIPTION = "authority_and_track_description"
    """MA + SSP + gradient on board, the front end in no on-sight area."""
    ON_SIGHT_AUTHORITY = "on_sight_authority"
    """MA + SSP + gradient on board, the front end in an on-sight area."""
    AUTOMATIC_DRIVING_ENGAGED = "automatic_driving_engaged"
    START_IN_STAFF_RESPONSIBLE = "start_in_staff_responsible"


@dataclass(frozen=True, kw_only=True)
class ModeTransition:
    """One row of the transition table."""

    sources: frozenset[EtcsMode]
    target: EtcsMode
    condition: ModeCondition
    priority: int
    condition_number: int | None = None
    """Number of the condition in SUBSET-026 §4.6.3, where DOMAIN.md gives it."""
    levels: frozenset[EtcsLevel] = _BOTH_LEVELS


@dataclass(frozen=True, kw_only=True)
class ModeChange:
    """A transition taken, when and from which mode."""

    time_s: float
    source: EtcsMode
    target: EtcsMode
    transition: ModeTransition


def _modes(*modes: EtcsMode) -> frozenset[EtcsMode]:
    return frozenset(modes)


_SUPERVISED = SUPERVISED_MODES
_C = ModeCondition

MODE_TRANSITIONS: tuple[ModeTransition, ...] = (
    ModeTransition(
        sources=MODELLED_MODES - {EtcsMode.IS},
        target=EtcsMode.IS,
        condition=_C.ISOLATED,
        priority=1,
    ),
    ModeTransition(
        sources=_modes(EtcsMode.IS), target=EtcsMode.SB, condition=_C.INSERTED, priority=1
    ),
    ModeTransition(
        sources=_SUPERVISED,
        target=EtcsMode.TR,
        condition=_C.END_OF_AUTHORITY_PASSED,
        priority=4,
        condition_number=12,
        levels=frozenset({EtcsLevel.LEVEL_1}),
    ),
    ModeTransition(
        sources=_SUPERVISED,
        target=EtcsMode.TR,
        condition=_C.END_OF_AUTHORITY_PASSED,
        priority=4,
        condition_number=16,
        levels=frozenset({EtcsLevel.LEVEL_2}),
    ),
    ModeTransition(
        sources=_SUPERVISED,
        target=EtcsMode.TR,
        condition=_C.BALISE_GROUP_AT_END_OF_AUTHORITY,
        priority=4,
        condition_number=11,
    ),
    ModeTransition(
        sources=_SUPERVISED,
        target=EtcsMode.TR,
        condition=_C.LINKING_REACTION,
        priority=4,
        condition_number=17,
    ),
    ModeTransition(
        sources=_SUPERVISED | {EtcsMode.SR},
        target=EtcsMode.TR,
        condition=_C.EMERGENCY_STOP,
        priority=4,
        condition_number=20,
    ),
    ModeTransition(
        sources=_modes(EtcsMode.SR),
        target=EtcsMode.TR,
        condition=_C.STAFF_RESPONSIBLE_DISTANCE_PASSED,
        priority=4,
        condition_number=42,
    ),
    ModeTransition(
        sources=_modes(EtcsMode.TR),
        target=EtcsMode.PT,
        condition=_C.TRIP_ACKNOWLEDGED,
        priority=4,
        condition_number=7,
    ),
    ModeTransition(
        sources=_modes(EtcsMode.AD),
        target=EtcsMode.FS,
        condition=_C.BRAKE_COMMANDED,
        priority=5,
        condition_number=24,
    ),
    ModeTransition(
        sources=_modes(EtcsMode.AD),
        target=EtcsMode.FS,
        condition=_C.AUTOMATIC_DRIVING_DISENGAGED,
        priority=5,
        condition_number=53,
    ),
    ModeTransition(
        sources=_modes(EtcsMode.SB),
        target=EtcsMode.FS,
        condition=_C.AUTHORITY_AND_TRACK_DESCRIPTION,
        priority=6,
        condition_number=10,
    ),
    ModeTransition(
        sources=_modes(EtcsMode.SR),
        target=EtcsMode.FS,
        condition=_C.AUTHORITY_AND_TRACK_DESCRIPTION,
        priority=6,
        condition_number=32,
        levels=frozenset({EtcsLevel.LEVEL_1}),
    ),
    ModeTransition(
        sources=_modes(EtcsMode.SR),
        target=EtcsMode.FS,
        condition=_C.AUTHORITY_AND_TRACK_DESCRIPTION,
        priority=6,
        condition_number=31,
        levels=frozenset({EtcsLevel.LEVEL_2}),
    ),
    ModeTransition(
        sources=_modes(EtcsMode.PT, EtcsMode.OS),
        target=EtcsMode.FS,
        condition=_C.AUTHORITY_AND_TRACK_DESCRIPTION,
        priority=6,
        condition_number=31,
    ),
    ModeTransition(
        sources=_modes(EtcsMode.SB, EtcsMode.SR, EtcsMode.PT, EtcsMode.FS),
        target=EtcsMode.OS,
        condition=_C.ON_SIGHT_AUTHORITY,
        priority=6,
    ),
    ModeTransition(
        sources=_modes(EtcsMode.FS),
        target=EtcsMode.AD,
        condition=_C.AUTOMATIC_DRIVING_ENGAGED,
        priority=7,
        condition_number=80,
    ),
    ModeTransition(
        sources=_modes(EtcsMode.SB, EtcsMode.PT),
        target=EtcsMode.SR,
        condition=_C.START_IN_STAFF_RESPONSIBLE,
        priority=7,
    ),
)
"""The transition table (see the module's docstring)."""


def select_transition(
    mode: EtcsMode, conditions: Set[ModeCondition], level: EtcsLevel
) -> ModeTransition | None:
    """The transition to take from ``mode`` when ``conditions`` hold, or None.

    Among the matching rows the lowest priority number wins; between equals, the first row.
    """
    best: ModeTransition | None = None
    for transition in MODE_TRANSITIONS:
        if (
            mode in transition.sources
            and transition.condition in conditions
            and level in transition.levels
            and (best is None or transition.priority < best.priority)
        ):
            best = transition
    return best
