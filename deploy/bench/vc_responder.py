"""AtoObResponder: a test double that answers the VC like a healthy ATO-OB with its operator.

The real ATO-OB answers from its own state and relays to ATO-TS what needs the remote operator
(vigilance, EB request, ETCS isolation/insertion, EB rearm). Until that wiring lands, this
double stands for both: it answers every request it receives (S3, S4) in the tick it arrives,
and plays the operator from a script of :class:`OperatorAction`. Its :class:`ResponderFault`
make it misbehave as the seeds' scenarios need.

The operator, by default, confirms each vigilance request and each EB rearm request
``reaction_s`` after it first sees it; EB requests, ETCS isolation or insertion, and leaving or
coming back to the console are scripted actions. A confirmation is bound to one request (its
sequence number): answering a newer request takes a new decision.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum

from onboard.runtime.clock import NS_PER_S
from onboard.vc import VcInputError
from onboard.vc.link import FaultyLink
from onboard.vc.messages import (
    SECTIONS,
    AtoObResponse,
    AtoObStatus,
    Section,
    SectionResponse,
    VcRequest,
)

__all__ = [
    "OPERATOR_REACTION_S",
    "AtoObResponder",
    "OperatorAction",
    "OperatorActionKind",
    "ResponderFault",
    "ResponderFaultKind",
]

OPERATOR_REACTION_S = 0.3
"""⚠ The remote operator's reaction time to a request shown on the console."""


class OperatorActionKind(StrEnum):
    REQUEST_EB = "request_eb"
    REQUEST_ETCS_ISOLATION = "request_etcs_isolation"
    REQUEST_ETCS_INSERTION = "request_etcs_insertion"
    CONFIRM_REARM = "confirm_rearm"
    """Needed only when the operator does not confirm rearms by himself."""
    LEAVE = "leave"
    """The operator leaves the console: vigilance requests go unanswered."""
    RETURN = "return"


@dataclass(frozen=True, kw_only=True)
class OperatorAction:
    at_s: float
    kind: OperatorActionKind


class ResponderFaultKind(StrEnum):
    STATUS_FAIL = "status_fail"
    """The ATO-OB reports FAIL (scenario B)."""
    SILENT = "silent"
    """The ATO-OB stops answering."""
    WRONG_INCREMENT = "wrong_increment"
    """An enabled section comes back incremented by two."""
    UNSOLICITED_INCREMENT = "unsolicited_increment"
    """A section not asked for comes back incremented."""


@dataclass(frozen=True, kw_only=True)
class ResponderFault:
    """The ATO-OB misbehaves in ``[start_s, end_s)``."""

    kind: ResponderFaultKind
    start_s: float
    end_s: float = math.inf
    section: Section = Section.ATO_VITALITY
    """The section a WRONG_ or UNSOLICITED_INCREMENT applies to."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start_s) and self.end_s > self.start_s):
            raise VcInputError(
                f"a fault window needs start < end, got {self.start_s}, {self.end_s}"
            )

    def active(self, now_s: float) -> bool:
        return self.start_s <= now_s < self.end_s


@dataclass
class _Instance:
    """One standing request as the ATO-OB sees it: its number and the operator's decision."""

    number: int
    first_seen_s: float
    decided_s: float | None = None
    """When the operator's "yes" takes effect [s]; None while he has not decided."""


_ACTION_SECTION = {
    OperatorActionKind.REQUEST_ETCS_ISOLATION: Section.ETCS_ISOLATION_CONFIRMATION,
    OperatorActionKind.REQUEST_ETCS_INSERTION: Section.ETCS_INSERTION_CONFIRMATION,
    OperatorActionKind.CONFIRM_REARM: Section.EB_REARM_CONFIRMATION,
}


@dataclass
class _Operator:
    present: bool = True
    eb_requested: bool = False
    intents: dict[Section, float] = field(default_factory=dict)
    """Decisions taken before the request they answer has come: since when."""


class AtoObResponder:
    """A healthy ATO-OB (and its operator), answering on ``response_link``.

    Parameters
    ----------
    request_link, response_link
        The link's two directions; the responder reads the first and writes the second.
    reaction_s
        The operator's reaction time [s].
    auto_confirm_rearm
        The operator confirms every EB rearm request by himself.
    actions, faults
        The operator's script and the faults to inject.
    """

    def __init__(
        self,
        request_link: FaultyLink[VcRequest],
        response_link: FaultyLink[AtoObResponse],
        *,
        sequence_modulo: int = 256,
        reaction_s: float = OPERATOR_REACTION_S,
        auto_confirm_rearm: bool = True,
        actions: Sequence[OperatorAction] = (),
        faults: Sequence[ResponderFault] = (),
    ) -> None:
        self._request_link = request_link
        self._response_link = response_link
        self.sequence_modulo = sequence_modulo
        self.reaction_s = reaction_s
        self.auto_confirm_rearm = auto_confirm_rearm
        self._actions = sorted(actions, key=lambda a: a.at_s)
        self._next_action = 0
        self.faults = tuple(faults)
        self._operator = _Operator()
        self._instances: dict[Section, _Instance] = {}
        self.last_request: VcRequest | None = None
        self.requests_received = 0
        self.responses_sent = 0
        self.balise_headers_seen: list[int] = []
        """NID_BG of each new balise telegram header forwarded by the VC."""

    def step_ns(self, release_ns: int) -> None:
        """:meth:`step` for an :class:`onboard.runtime.Executive` task."""
        self.step(release_ns / NS_PER_S)

    def step(self, now_s: float) -> None:
        """Play the operator's actions due, then answer every request arrived by ``now_s``."""
        while self._next_action < len(self._actions):
            action = self._actions[self._next_action]
            if action.at_s > now_s:
                break
            self._act(action)
            self._next_action += 1
        for delivery in self._request_link.receive(now_s):
            self._answer(delivery.message, now_s)

    def _act(self, action: OperatorAction) -> None:
        operator = self._operator
        if action.kind is OperatorActionKind.REQUEST_EB:
            operator.eb_requested = True
        elif action.kind is OperatorActionKind.LEAVE:
            operator.present = False
        elif action.kind is OperatorActionKind.RETURN:
            operator.present = True
        else:
            operator.intents[_ACTION_SECTION[action.kind]] = action.at_s

    def _active(self, kind: ResponderFaultKind, now_s: float) -> list[ResponderFault]:
        return [f for f in self.faults if f.kind is kind and f.active(now_s)]

    def _answer(self, request: VcRequest, now_s: float) -> None:
        self.requests_received += 1
        self.last_request = request
        header = request.last_balise_header
        if header is not None and (
            not self.balise_headers_seen or self.balise_headers_seen[-1] != header.nid_bg
        ):
            self.balise_headers_seen.append(header.nid_bg)
        if self._active(ResponderFaultKind.SILENT, now_s):
            return
        wrong = {f.section for f in self._active(ResponderFaultKind.WRONG_INCREMENT, now_s)}
        unasked = {f.section for f in self._active(ResponderFaultKind.UNSOLICITED_INCREMENT, now_s)}
        sections = []
        for section in SECTIONS:
            asked = request.section(section)
            number = asked.sequence_number
            if asked.request_flag:
                step = 2 if section in wrong else 1
                answer = self._decide(section, number, now_s)
            else:
                step = 1 if section in unasked else 0
                answer = False
            sections.append(SectionResponse((number + step) % self.sequence_modulo, answer))
        failing = self._active(ResponderFaultKind.STATUS_FAIL, now_s)
        status = AtoObStatus.FAIL if failing else AtoObStatus.OK
        self._response_link.send(AtoObResponse(sections=tuple(sections), status=status), now_s)
        self.responses_sent += 1

    def _decide(self, section: Section, number: int, now_s: float) -> bool:
        operator = self._operator
        if section is Section.ATO_VITALITY:
            return True
        if section is Section.EB_RELEASE_CONFIRMATION:
            requested, operator.eb_requested = operator.eb_requested, False
            return requested
        instance = self._instances.get(section)
        if instance is None or instance.number != number:
            instance = self._instances[section] = _Instance(number, now_s)
        if instance.decided_s is None:
            if section is Section.OPERATOR_VIGILANCE:
                if operator.present:
                    instance.decided_s = now_s + self.reaction_s
            elif section is Section.EB_REARM_CONFIRMATION and self.auto_confirm_rearm:
                instance.decided_s = now_s + self.reaction_s
            elif section in operator.intents:
                since_s = operator.intents.pop(section)
                instance.decided_s = max(since_s, instance.first_seen_s) + self.reaction_s
        return instance.decided_s is not None and instance.decided_s <= now_s
