"""The VC ↔ ATO-OB exchange (seeds 001, 004; DOMAIN.md §7.2): request, response, what they carry.

Every 40 ms Task A sends a :class:`VcRequest` of six sections, each a sequence number and a
request flag (S1, S2). A flag going 0 → 1 increments its section's sequence number. The ATO-OB
answers with an :class:`AtoObResponse`: each enabled section with its sequence number
incremented by one (S3) and an answer flag, each disabled section with its number unchanged,
and always its operational status OK or FAIL (S4). A response is valid only if every number is
exactly that (S5).

Two sections are *pulsed*: ATO Vitality and EB Release Confirmation are asked afresh in every
request (the flag drops between two requests), so their numbers move every 40 ms and a stale or
replayed response can never pass as a new one. The other four are *standing*: the flag stays up,
with one number, until the question is settled.

What the answer flag means per section (the seeds give the sections, not the flags' meaning;
this is our reading, docs/vc.md):

- ATO Vitality: the ATO-OB is alive (always set when it answers);
- Operator Vigilance: the remote operator has confirmed his presence for this request;
- EB Release Confirmation: the operator asks for the emergency brake (scenario A);
- ETCS Isolation / Insertion Confirmation: the operator confirms the ETCS-OB be switched
  off / on by the VC's radio relay;
- EB Rearm Confirmation: the operator confirms the EB may be rearmed.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import IntEnum, StrEnum

from onboard.etcs.balises import TelegramHeader
from onboard.vc._exceptions import VcInputError

__all__ = [
    "DECAY_CONDITIONS",
    "PULSED_SECTIONS",
    "SECTIONS",
    "AtoObResponse",
    "AtoObStatus",
    "DecayReason",
    "EbCondition",
    "Notification",
    "Section",
    "SectionRequest",
    "SectionResponse",
    "VcRequest",
    "expected_response_number",
]


class Section(StrEnum):
    """The six request sections, in message order (seed 004, S1)."""

    ATO_VITALITY = "ato_vitality"
    OPERATOR_VIGILANCE = "operator_vigilance"
    EB_RELEASE_CONFIRMATION = "eb_release_confirmation"
    ETCS_INSERTION_CONFIRMATION = "etcs_insertion_confirmation"
    ETCS_ISOLATION_CONFIRMATION = "etcs_isolation_confirmation"
    EB_REARM_CONFIRMATION = "eb_rearm_confirmation"


SECTIONS: tuple[Section, ...] = tuple(Section)
"""The sections in the order they travel."""
_INDEX = {section: index for index, section in enumerate(SECTIONS)}

PULSED_SECTIONS = frozenset({Section.ATO_VITALITY, Section.EB_RELEASE_CONFIRMATION})
"""Sections asked afresh in every request (a new sequence number each time)."""


class AtoObStatus(StrEnum):
    """The ATO-OB's operational status, sent with every response (S4)."""

    OK = "ok"
    FAIL = "fail"


class EbCondition(IntEnum):
    """Why Task B raises the EB flag: the six conditions of seed 004 (DOMAIN.md §7.2)."""

    OPERATOR_REQUEST = 1
    """The remote operator asks for the EB through the ATO-OB (scenario A)."""
    ATO_OB_FAIL = 2
    """The ATO-OB reports FAIL (scenario B)."""
    RESPONSE_NOT_VALID = 3
    """A response whose sequence numbers are not correctly incremented (scenarios C, E)."""
    CONFIRMATION_TIMEOUT = 4
    """Vitality or vigilance not confirmed within its time limit (scenarios D, N)."""
    ODOMETRY_NOT_EFFICIENT = 5
    """ETCS isolated and the odometry not efficient (scenario M)."""
    OVERSPEED_ETCS_ISOLATED = 6
    """ETCS isolated and the speed above 30 km/h (scenario L)."""


DECAY_CONDITIONS = frozenset(
    {EbCondition.ATO_OB_FAIL, EbCondition.RESPONSE_NOT_VALID, EbCondition.CONFIRMATION_TIMEOUT}
)
"""Conditions 2, 3 and 4 also set System Decay."""


class DecayReason(StrEnum):
    """Why the VC entered System Decay (the train stays stopped until a restart)."""

    ATO_OB_FAIL = "ato_ob_fail"
    RESPONSE_NOT_VALID = "response_not_valid"
    VITALITY_TIMEOUT = "vitality_timeout"
    VIGILANCE_TIMEOUT = "vigilance_timeout"
    ETCS_ISOLATION_NOT_ACTUATED = "etcs_isolation_not_actuated"
    ETCS_INSERTION_NOT_ACTUATED = "etcs_insertion_not_actuated"
    EB_REARM_NOT_APPLIED = "eb_rearm_not_applied"


class Notification(StrEnum):
    """States the VC reports to the ATO-OB in every request (for the operator and the log)."""

    EB_APPLIED = "eb_applied"
    SYSTEM_DECAY = "system_decay"
    ETCS_ISOLATED = "etcs_isolated"
    ODOMETRY_NOT_EFFICIENT = "odometry_not_efficient"
    STANDSTILL = "standstill"
    REARM_REQUESTED = "rearm_requested"


@dataclass(frozen=True, slots=True)
class SectionRequest:
    """One request section: its sequence number and its request flag (S2)."""

    sequence_number: int
    request_flag: bool


@dataclass(frozen=True, slots=True)
class SectionResponse:
    """One response section: the sequence number as the ATO-OB returns it, and its answer."""

    sequence_number: int
    answer: bool


def _check_sections(sections: tuple[SectionRequest, ...] | tuple[SectionResponse, ...]) -> None:
    if len(sections) != len(SECTIONS):
        raise VcInputError(f"a message has {len(SECTIONS)} sections, got {len(sections)}")
    for item in sections:
        if not 0 <= item.sequence_number < 65_536:
            raise VcInputError(f"sequence number out of range: {item.sequence_number}")


@dataclass(frozen=True, slots=True, kw_only=True)
class VcRequest:
    """Task A's request to the ATO-OB (seed 004 §2.4)."""

    sent_s: float
    """When Task A sent it [s]."""
    sections: tuple[SectionRequest, ...]
    """The six sections, in :data:`SECTIONS` order."""
    estimated_speed_mps: float | None
    """Task B's tachometer speed [m/s]; None while the odometry is not efficient."""
    estimated_position_m: float | None
    """Task B's tachometer distance since power-up [m]; None before the first frame."""
    last_balise_header: TelegramHeader | None
    """The header of the last balise telegram read by the BTM."""
    notifications: tuple[Notification, ...] = ()
    eb_conditions: tuple[EbCondition, ...] = ()
    """The conditions behind the EB flag now raised."""
    decay_reasons: tuple[DecayReason, ...] = ()

    def __post_init__(self) -> None:
        _check_sections(self.sections)

    def section(self, section: Section) -> SectionRequest:
        return self.sections[_INDEX[section]]


@dataclass(frozen=True, slots=True, kw_only=True)
class AtoObResponse:
    """The ATO-OB's answer to one request (S3, S4)."""

    sections: tuple[SectionResponse, ...]
    status: AtoObStatus

    def __post_init__(self) -> None:
        _check_sections(self.sections)

    def section(self, section: Section) -> SectionResponse:
        return self.sections[_INDEX[section]]

    def with_section(self, section: Section, value: SectionResponse) -> AtoObResponse:
        """A copy with one section replaced (fault injection)."""
        sections = list(self.sections)
        sections[_INDEX[section]] = value
        return replace(self, sections=tuple(sections))


def expected_response_number(request: SectionRequest, modulo: int) -> int:
    """The number a valid response carries: incremented if the flag is up, unchanged if not."""
    if request.request_flag:
        return (request.sequence_number + 1) % modulo
    return request.sequence_number
