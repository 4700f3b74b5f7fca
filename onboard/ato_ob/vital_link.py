"""VitalLink: the ATO-OB's end of the Vital Control link (seeds 001, 004; DOMAIN.md §7.2).

The VC sends a :class:`~onboard.vc.messages.VcRequest` every 40 ms; the ATO-OB answers each one
from its own state and from the remote operator's decisions, which reach it as trackside
commands. The link is the only way the two meet (ARCHITECTURE.md), so that it can be delayed,
dropped or corrupted by fault injection.

How each section is answered (the numbers follow S3: incremented when the flag is up):

- **ATO Vitality**: yes, whenever the ATO-OB answers at all;
- **EB Release Confirmation**: yes once after the operator pressed the EB (a pulse);
- **Operator Vigilance, EB Rearm, ETCS Isolation, ETCS Insertion Confirmation**: standing
  requests. Each new one (a new number) becomes an :class:`PendingRequest` that the node
  relays to ATO-TS in its status reports; it is answered yes once the operator confirmed *that
  number* (:meth:`VitalLink.confirm`), so a late answer never confirms a newer request.

The status is FAIL while the ATO-OB controller is in FA or has an internal fault (condition 2:
the VC brakes and enters System Decay). Faults can be injected for scenario runs: the ATO-OB
going silent, or reporting FAIL.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType

from onboard.vc.link import FaultyLink
from onboard.vc.messages import (
    SECTIONS,
    AtoObResponse,
    AtoObStatus,
    Section,
    SectionResponse,
    VcRequest,
    expected_response_number,
)
from protocol.messages import OperatorRequestKind

__all__ = ["SECTION_OF_REQUEST", "PendingRequest", "VitalLink"]

SECTION_OF_REQUEST = MappingProxyType(
    {
        OperatorRequestKind.VIGILANCE: Section.OPERATOR_VIGILANCE,
        OperatorRequestKind.EB_REARM: Section.EB_REARM_CONFIRMATION,
        OperatorRequestKind.ETCS_ISOLATION: Section.ETCS_ISOLATION_CONFIRMATION,
        OperatorRequestKind.ETCS_INSERTION: Section.ETCS_INSERTION_CONFIRMATION,
    }
)
"""The VC section behind each kind of operator request."""
_REQUEST_OF_SECTION = {section: kind for kind, section in SECTION_OF_REQUEST.items()}


@dataclass(frozen=True, kw_only=True)
class PendingRequest:
    """A standing VC request waiting for (or holding) the operator's answer."""

    kind: OperatorRequestKind
    number: int
    raised_s: float
    """When the request carrying this number was sent by the VC [s]."""
    deadline_s: float | None
    """When the VC brakes if it is still unanswered [s] (vigilance only)."""
    confirmed: bool = False


@dataclass
class _Counters:
    requests: int = 0
    responses: int = 0
    emergency_brakes_relayed: int = 0


@dataclass
class VitalLink:
    """The ATO-OB's side of one VC link.

    Parameters
    ----------
    request_link, response_link
        The link's two directions: requests are read from the first, answers written on the
        second.
    vigilance_timeout_s
        The VC's time limit for a vigilance answer [s], for the deadline shown to the operator.
    sequence_modulo
        The sections' number range (one byte).
    """

    request_link: FaultyLink[VcRequest]
    response_link: FaultyLink[AtoObResponse]
    vigilance_timeout_s: float
    sequence_modulo: int = 256
    silent: bool = False
    """Injected fault: the ATO-OB stops answering (scenario N)."""
    reports_failure: bool = False
    """Injected fault: the ATO-OB answers FAIL (scenario B)."""
    counters: _Counters = field(default_factory=_Counters, init=False)
    last_request: VcRequest | None = field(default=None, init=False)
    _pending: dict[OperatorRequestKind, PendingRequest] = field(default_factory=dict, init=False)
    _raised: list[PendingRequest] = field(default_factory=list, init=False)
    _emergency_brake: bool = field(default=False, init=False)

    @property
    def pending(self) -> tuple[PendingRequest, ...]:
        """The standing requests of the last request received, in section order."""
        return tuple(self._pending[kind] for kind in SECTION_OF_REQUEST if kind in self._pending)

    def take_raised(self) -> list[PendingRequest]:
        """The requests raised since the last call (for the event log)."""
        raised, self._raised = self._raised, []
        return raised

    def request_emergency_brake(self) -> None:
        """The operator's EB: answered yes in the next EB Release Confirmation."""
        self._emergency_brake = True

    def refusal(self, kind: OperatorRequestKind, number: int) -> str | None:
        """Why the operator's answer to request ``number`` of ``kind`` cannot be taken now."""
        pending = self._pending.get(kind)
        if pending is None:
            return f"no {kind.value} request pending"
        if pending.number != number:
            return f"{kind.value} request {number} is not the pending one ({pending.number})"
        return None

    def confirm(self, kind: OperatorRequestKind, number: int) -> str | None:
        """The operator answers request ``number`` of ``kind``; the refusal, if refused."""
        refused = self.refusal(kind, number)
        if refused is not None:
            return refused
        pending = self._pending[kind]
        if not pending.confirmed:
            self._pending[kind] = PendingRequest(
                kind=kind,
                number=number,
                raised_s=pending.raised_s,
                deadline_s=pending.deadline_s,
                confirmed=True,
            )
        return None

    def step(self, now_s: float, *, failed: bool) -> None:
        """Answer every request arrived by ``now_s``; ``failed``: the ATO-OB is in failure."""
        for delivery in self.request_link.receive(now_s):
            self._take(delivery.message)
            if self.silent:
                continue
            status = AtoObStatus.FAIL if failed or self.reports_failure else AtoObStatus.OK
            self.response_link.send(self._answer(delivery.message, status), now_s)
            self.counters.responses += 1

    def _take(self, request: VcRequest) -> None:
        self.counters.requests += 1
        self.last_request = request
        for section in SECTIONS:
            kind = _REQUEST_OF_SECTION.get(section)
            if kind is None:
                continue
            asked = request.section(section)
            current = self._pending.get(kind)
            if not asked.request_flag:
                self._pending.pop(kind, None)
            elif current is None or current.number != asked.sequence_number:
                deadline = None
                if kind is OperatorRequestKind.VIGILANCE:
                    deadline = request.sent_s + self.vigilance_timeout_s
                raised = PendingRequest(
                    kind=kind,
                    number=asked.sequence_number,
                    raised_s=request.sent_s,
                    deadline_s=deadline,
                )
                self._pending[kind] = raised
                self._raised.append(raised)

    def _answer(self, request: VcRequest, status: AtoObStatus) -> AtoObResponse:
        sections = []
        for section in SECTIONS:
            asked = request.section(section)
            answer = False
            if asked.request_flag:
                if section is Section.ATO_VITALITY:
                    answer = True
                elif section is Section.EB_RELEASE_CONFIRMATION:
                    answer, self._emergency_brake = self._emergency_brake, False
                    self.counters.emergency_brakes_relayed += answer
                else:
                    pending = self._pending.get(_REQUEST_OF_SECTION[section])
                    answer = pending is not None and pending.confirmed
            number = expected_response_number(asked, self.sequence_modulo)
            sections.append(SectionResponse(number, answer))
        return AtoObResponse(sections=tuple(sections), status=status)
