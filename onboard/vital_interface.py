"""The onboard's side of the Vital Control: its links, its brake, its relay, its events.

The ATO-OB and the VC talk only through the VC request/response messages of seeds 001/004
(:class:`~onboard.ato_ob.vital_link.VitalLink`, one per board); :class:`VitalInterface` holds those
links, relays the operator's emergency brake and confirmations to every board, follows the
ETCS isolation relay, and turns what the VC raised since the last step into events for the
trackside's log. Without a VC fitted every request is refused and no brake is applied.
"""

from __future__ import annotations

from onboard.ato_ob.vital_link import PendingRequest, VitalLink
from onboard.etcs import EtcsOnboard
from onboard.events import StackEvent
from onboard.vc.installation import VcInstallation
from onboard.vc.ipc import VcEventKind
from protocol import messages as m

__all__ = ["NO_VITAL_CONTROL", "VitalInterface"]

NO_VITAL_CONTROL = "no Vital Control fitted"
"""The refusal of an operator request to the VC when none is fitted."""
_VC_ALARMS = frozenset(
    {VcEventKind.EB_CONDITION, VcEventKind.SYSTEM_DECAY, VcEventKind.EB_COMMANDED}
)


class VitalInterface:
    """The ATO-OB's links to the VC boards of ``vital`` (None: no VC fitted)."""

    def __init__(self, vital: VcInstallation | None) -> None:
        self.vital = vital
        self.links = (
            [
                VitalLink(
                    request,
                    response,
                    vigilance_timeout_s=vital.config.vigilance_timeout_s,
                    sequence_modulo=vital.config.sequence_modulo,
                )
                for request, response in vital.links
            ]
            if vital is not None
            else []
        )
        self._vc_events_seen = (0, 0)
        self._pair_events_seen = 0

    @property
    def eb_commanded(self) -> bool:
        return self.vital is not None and self.vital.eb_commanded

    def emergency_brake(self, now_s: float) -> float:
        """The EB's share of the full brake force on the plant now, 0 to 1 (0 without a VC)."""
        return 0.0 if self.vital is None else self.vital.emergency_brake(now_s)

    def confirm_refusal(self, kind: m.OperatorRequestKind, number: int) -> str | None:
        """Why the operator's answer to a VC request cannot be taken, if it cannot."""
        if not self.links:
            return NO_VITAL_CONTROL
        return self.links[0].refusal(kind, number)

    def operator_emergency_brake(self) -> str | None:
        """The operator's EB, relayed to the VC; the refusal, if refused."""
        if not self.links:
            return NO_VITAL_CONTROL
        for link in self.links:
            link.request_emergency_brake()
        return None

    def operator_confirm(self, kind: m.OperatorRequestKind, number: int) -> str | None:
        """The operator's answer to a VC request; the refusal, if refused."""
        if not self.links:
            return NO_VITAL_CONTROL
        refusals = [link.confirm(kind, number) for link in self.links]
        return refusals[0]

    def step(self, now_s: float, *, ato_failed: bool) -> list[StackEvent]:
        """The ATO-OB answers the VC's requests; the operator requests and VC events raised
        since the last step, as events."""
        for link in self.links:
            link.step(now_s, failed=ato_failed)
        if self.vital is None:
            return []
        events = [_request_event(request) for request in self.links[0].take_raised()]
        vc = self.vital.boards[0].vc
        seen_b, seen_c = self._vc_events_seen
        raised = sorted(
            vc.task_b.events[seen_b:] + vc.task_c.events[seen_c:], key=lambda e: e.time_s
        )
        self._vc_events_seen = (len(vc.task_b.events), len(vc.task_c.events))
        events.extend(
            StackEvent(
                m.EventSeverity.ERROR if event.kind in _VC_ALARMS else m.EventSeverity.INFO,
                f"vc.{event.kind.value}",
                f"{event.task}: {event.detail}",
            )
            for event in raised
        )
        pair = self.vital.pair
        if pair is not None:
            events.extend(
                StackEvent(
                    m.EventSeverity.ERROR,
                    f"vc.pair.{pair_event.kind.value}",
                    f"replica {pair_event.replica}: {pair_event.detail}",
                )
                for pair_event in pair.events[self._pair_events_seen :]
            )
            self._pair_events_seen = len(pair.events)
        return events

    def follow_relay(self, etcs: EtcsOnboard, now_s: float) -> None:
        """The relay's contact switches the ETCS-OB's power: isolated, or inserted and started."""
        if self.vital is None:
            return
        isolated = self.vital.etcs_isolated(now_s)
        if isolated and not etcs.isolated:
            etcs.isolate(now_s)
        elif not isolated and etcs.isolated:
            etcs.insert(now_s)
            etcs.start_of_mission(now_s)

    def status(self) -> m.VitalControlStatus | None:
        """The VC's state for the status report, with the requests waiting for the operator."""
        if self.vital is None:
            return None
        out = self.vital.outputs
        return m.VitalControlStatus(
            eb_commanded=self.vital.eb_commanded,
            system_decay=out.system_decay,
            decay_reasons=tuple(reason.value for reason in out.decay_reasons),
            eb_conditions=tuple(int(condition) for condition in out.eb_conditions),
            etcs_isolated=out.etcs_isolated,
            supervision_state=out.task_b_state.value,
            brake_state=out.brake_state.value,
            etcs_state=out.etcs_state.value,
            standstill=out.standstill,
            odometry_efficient=out.odometry_efficient,
            speed_mps=None if out.speed_mps is None else max(out.speed_mps, 0.0),
            replicas=len(self.vital.boards),
            pair_tripped=self.vital.tripped,
            operator_requests=tuple(
                m.OperatorRequest(
                    kind=p.kind,
                    number=p.number,
                    raised_s=p.raised_s,
                    deadline_s=p.deadline_s,
                    confirmed=p.confirmed,
                )
                for p in self.links[0].pending
            ),
        )


def _request_event(request: PendingRequest) -> StackEvent:
    """A VC request raised for the operator, as an event (urgent when it has a deadline)."""
    text = f"{request.kind.value} request {request.number}"
    if request.deadline_s is not None:
        text += f", answer by {request.deadline_s:.2f} s"
    urgent = request.deadline_s is not None
    severity = m.EventSeverity.WARNING if urgent else m.EventSeverity.INFO
    return StackEvent(severity, f"vc.request.{request.kind.value}", text)
