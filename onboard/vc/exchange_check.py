"""Task B's check of the request/response exchange with the ATO-OB (seed 004 §2.4, rows B1–B2).

:class:`ExchangeCheck` keeps what Task B must know of the requests Task A sent: the outstanding
ones by the ATO Vitality number their response must carry, with their deadline; the standing
confirmation sections' current numbers and the numbers confirmed; the vigilance deadline. Each
cycle it registers the new requests, checks the responses that arrived and the deadlines, and
notes what it finds in the cycle's :class:`Findings`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from onboard.vc.config import TIME_TOLERANCE_S, VcConfig
from onboard.vc.ipc import Delivery
from onboard.vc.messages import (
    SECTIONS,
    AtoObResponse,
    AtoObStatus,
    DecayReason,
    EbCondition,
    Section,
    VcRequest,
    expected_response_number,
)

__all__ = ["CONFIRMED_SECTIONS", "ExchangeCheck", "Findings"]

CONFIRMED_SECTIONS = (
    Section.OPERATOR_VIGILANCE,
    Section.ETCS_ISOLATION_CONFIRMATION,
    Section.ETCS_INSERTION_CONFIRMATION,
    Section.EB_REARM_CONFIRMATION,
)
"""The standing sections whose answer is a confirmation Task B passes on."""

_C = EbCondition


@dataclass(slots=True)
class Findings:
    """The EB conditions and decay reasons one cycle found, each with its evidence time."""

    conditions: dict[EbCondition, float] = field(default_factory=dict)
    decays: list[tuple[DecayReason, float]] = field(default_factory=list)

    def note(self, condition: EbCondition, evidence_s: float) -> None:
        """A condition found; the first evidence of the cycle stands."""
        self.conditions.setdefault(condition, evidence_s)

    def decay(self, reason: DecayReason, condition: EbCondition, evidence_s: float) -> None:
        """A System Decay reason found, with the EB condition it raises."""
        self.decays.append((reason, evidence_s))
        self.conditions.setdefault(condition, evidence_s)


@dataclass(frozen=True, slots=True)
class _Outstanding:
    request: VcRequest
    deadline_s: float


class ExchangeCheck:
    """The requests Task B waits answers for, and the confirmations they brought."""

    def __init__(self, config: VcConfig) -> None:
        self.config = config
        self._outstanding: dict[int, _Outstanding] = {}
        self._current: dict[Section, int | None] = dict.fromkeys(CONFIRMED_SECTIONS)
        self._confirmed: dict[Section, int | None] = dict.fromkeys(CONFIRMED_SECTIONS)
        self._vigilance_deadline_s: float | None = None

    def register(self, request: VcRequest) -> None:
        """A request Task A sent: its response is awaited until the exchange window ends."""
        modulo = self.config.sequence_modulo
        vitality = request.section(Section.ATO_VITALITY).sequence_number
        deadline_s = request.sent_s + self.config.exchange_window_s
        self._outstanding[(vitality + 1) % modulo] = _Outstanding(request, deadline_s)
        for section in CONFIRMED_SECTIONS:
            item = request.section(section)
            number = item.sequence_number if item.request_flag else None
            if number != self._current[section]:
                self._confirmed[section] = None
            self._current[section] = number
        vigilance = self._current[Section.OPERATOR_VIGILANCE]
        if vigilance is None:
            self._vigilance_deadline_s = None
        elif self._confirmed[Section.OPERATOR_VIGILANCE] is None and (
            self._vigilance_deadline_s is None
        ):
            self._vigilance_deadline_s = request.sent_s + self.config.vigilance_timeout_s

    def check_response(
        self, delivery: Delivery[AtoObResponse], now_s: float, found: Findings
    ) -> None:
        """One response: matched to its request, in time, with the expected numbers and OK."""
        response, arrived_s = delivery.message, delivery.arrived_s
        vitality = response.section(Section.ATO_VITALITY).sequence_number
        outstanding = self._outstanding.pop(vitality, None)
        if outstanding is None:
            # A number no outstanding request expects: stale, replayed or corrupted.
            found.decay(DecayReason.RESPONSE_NOT_VALID, _C.RESPONSE_NOT_VALID, arrived_s)
            return
        if now_s > outstanding.deadline_s + TIME_TOLERANCE_S:
            found.decay(
                DecayReason.VITALITY_TIMEOUT, _C.CONFIRMATION_TIMEOUT, outstanding.deadline_s
            )
            return
        request = outstanding.request
        modulo = self.config.sequence_modulo
        for section in SECTIONS:
            expected = expected_response_number(request.section(section), modulo)
            if response.section(section).sequence_number != expected:
                found.decay(DecayReason.RESPONSE_NOT_VALID, _C.RESPONSE_NOT_VALID, arrived_s)
                return
        if response.status is AtoObStatus.FAIL:
            found.decay(DecayReason.ATO_OB_FAIL, _C.ATO_OB_FAIL, arrived_s)
        eb_release = Section.EB_RELEASE_CONFIRMATION
        if request.section(eb_release).request_flag and response.section(eb_release).answer:
            found.note(_C.OPERATOR_REQUEST, arrived_s)
        for section in CONFIRMED_SECTIONS:
            asked = request.section(section)
            if asked.request_flag and response.section(section).answer:
                self._confirmed[section] = asked.sequence_number
                if section is Section.OPERATOR_VIGILANCE:
                    self._vigilance_deadline_s = None

    def check_deadlines(self, now_s: float, found: Findings) -> None:
        """Requests left unanswered past their window, and an unconfirmed vigilance request."""
        overdue = [
            (key, outstanding)
            for key, outstanding in self._outstanding.items()
            if now_s > outstanding.deadline_s + TIME_TOLERANCE_S
        ]
        for key, outstanding in overdue:
            del self._outstanding[key]
            found.decay(
                DecayReason.VITALITY_TIMEOUT, _C.CONFIRMATION_TIMEOUT, outstanding.deadline_s
            )
        deadline_s = self._vigilance_deadline_s
        if deadline_s is not None and now_s > deadline_s + TIME_TOLERANCE_S:
            self._vigilance_deadline_s = None
            found.decay(DecayReason.VIGILANCE_TIMEOUT, _C.CONFIRMATION_TIMEOUT, deadline_s)

    def confirmed_number(self, section: Section) -> int | None:
        """The number of the standing request of ``section`` the ATO-OB confirmed, if any."""
        value = self._confirmed[section]
        return value if value == self._current[section] else None

    def thresholds_s(self) -> list[float]:
        """The instants past which a cycle with no input finds a deadline missed."""
        thresholds = [o.deadline_s + TIME_TOLERANCE_S for o in self._outstanding.values()]
        if self._vigilance_deadline_s is not None:
            thresholds.append(self._vigilance_deadline_s + TIME_TOLERANCE_S)
        return thresholds

    def state_key(self) -> tuple[object, ...]:
        """Everything a cycle can change here (the quiet cycles' fingerprint)."""
        return (
            tuple(self._outstanding.items()),
            tuple(self._current.values()),
            tuple(self._confirmed.values()),
            self._vigilance_deadline_s,
        )
