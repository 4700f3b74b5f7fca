"""The trackside side of the ATO-OB ↔ ATO-TS session (DOMAIN.md §2.3), as a pure state machine.

The bridge answers handshake requests with it, acknowledges status reports through it and asks
it, periodically, which sessions have timed out. Times are the caller's (wall or simulated), so
tests drive it deterministically.

- A handshake (HSReq) is accepted (HSAck with this trackside's id, a new session id, the
  protocol version, the response timeout and the status-report interval) when a supported
  version is offered and no other trackside is in charge of the vehicle; otherwise it is
  rejected (HSRej) with the reason.
- Each status report (STR) of an established session is acknowledged (STRAck). A report whose
  counter is not newer than the last one taken is stale: rejected and counted.
- Every command, journey profile, MA and TSR sent in a session carries its id and a number,
  +1 per message (:meth:`SessionManager.seal`): the onboard takes only those of the session it
  holds, each number once (``onboard.freshness``).
- A session is lost when no report arrived within the response timeout (in the vehicle's own
  time, seen when the next report comes), when the vehicle's liveliness token goes; either side
  may end it.
"""

from __future__ import annotations

import secrets
import threading
from dataclasses import dataclass, field

from protocol import messages as m

__all__ = ["SessionManager", "TracksideSession"]

SUPPORTED_VERSIONS = frozenset({1})


@dataclass
class TracksideSession:
    vehicle_id: str
    version: int
    opened_s: float
    last_report_s: float
    train_length_m: float | None = None
    """The train's length from its handshake [m] (its train data): the RBC's separation."""
    last_seq: int = -1
    reports: int = 0
    session_id: str = field(default_factory=lambda: secrets.token_urlsafe(12))
    """Unguessable, new for every session: a message of an earlier session is refused."""
    sent: int = 0
    """Messages sealed in this session so far (the last number given)."""


@dataclass
class SessionManager:
    trackside_id: str
    response_timeout_s: float = 3.0
    status_interval_s: float = 0.2
    in_charge_elsewhere: dict[str, str] = field(default_factory=dict)
    """Vehicle → the trackside in charge of it, when not this one."""
    sessions: dict[str, TracksideSession] = field(default_factory=dict)
    stale_reports: int = 0
    reports_outside_session: int = 0
    rejected: int = 0
    lost: int = 0
    _seal_lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def on_request(
        self, request: m.SessionRequest, now_s: float
    ) -> m.SessionAccept | m.SessionReject:
        """Answer a handshake request."""
        common = SUPPORTED_VERSIONS.intersection(request.supported_versions)
        reason: m.SessionRejectReason | None = None
        if not common:
            reason = m.SessionRejectReason.INCOMPATIBLE_VERSIONS
        elif request.vehicle_id in self.in_charge_elsewhere:
            reason = m.SessionRejectReason.OTHER_TRACKSIDE_IN_CHARGE
        if reason is not None:
            self.rejected += 1
            return m.SessionReject(trackside_id=self.trackside_id, reason=reason)
        version = max(common)
        self.sessions[request.vehicle_id] = TracksideSession(
            request.vehicle_id,
            version,
            opened_s=now_s,
            last_report_s=now_s,
            train_length_m=request.train_length_m,
        )
        return m.SessionAccept(
            trackside_id=self.trackside_id,
            session_id=self.sessions[request.vehicle_id].session_id,
            version=version,
            response_timeout_s=self.response_timeout_s,
            status_interval_s=self.status_interval_s,
        )

    def seal(self, vehicle_id: str) -> m.Freshness | None:
        """The session id and the next number for a message to the vehicle; ``None`` when no
        session is open with it (the onboard then refuses the message). Thread-safe."""
        with self._seal_lock:
            session = self.sessions.get(vehicle_id)
            if session is None:
                return None
            session.sent += 1
            return m.Freshness(session_id=session.session_id, number=session.sent)

    def on_status(self, report: m.StatusReport, now_s: float) -> m.StatusAck | None:
        """The STRAck for a report of an established session; None for a stale report or one
        outside any session (counted)."""
        session = self.sessions.get(report.vehicle_id)
        if session is None:
            self.reports_outside_session += 1
            return None
        if report.seq <= session.last_seq:
            self.stale_reports += 1
            return None
        # The gap is measured from the session's first report on: the handshake's own time is
        # only the vehicle's last report seen before it, which may be older than the handshake.
        if session.reports and now_s - session.last_report_s > self.response_timeout_s:
            # Reports stopped for longer than the timeout, in the vehicle's own time: the session
            # lapsed meanwhile. Not acknowledged, the onboard loses it too and shakes hands again.
            del self.sessions[report.vehicle_id]
            self.lost += 1
            return None
        session.last_seq = report.seq
        session.last_report_s = now_s
        session.reports += 1
        return m.StatusAck(vehicle_id=report.vehicle_id, seq=report.seq)

    def close(self, vehicle_id: str) -> bool:
        """The vehicle is gone (its liveliness token withdrawn): its session ends."""
        if self.sessions.pop(vehicle_id, None) is None:
            return False
        self.lost += 1
        return True

    def expire(self, now_s: float) -> list[str]:
        """Close the sessions with no report within the response timeout of ``now_s``, for
        callers with one time base for every vehicle (the bridge's vehicles each have their
        own simulated time, so it relies on :meth:`on_status` and :meth:`close`)."""
        lost = [
            vehicle
            for vehicle, session in self.sessions.items()
            if now_s - session.last_report_s > self.response_timeout_s
        ]
        for vehicle in lost:
            del self.sessions[vehicle]
        self.lost += len(lost)
        return lost

    def terminate(self, vehicle_id: str, reason: str) -> m.SessionTermination | None:
        """End a session from the trackside: the SESSTermReq to send, if one was open."""
        if self.sessions.pop(vehicle_id, None) is None:
            return None
        return m.SessionTermination(vehicle_id=vehicle_id, by="trackside", reason=reason)

    def on_termination(self, termination: m.SessionTermination) -> bool:
        """The onboard ended its session (SESSTerm)."""
        if termination.by != "onboard":
            return False
        return self.sessions.pop(termination.vehicle_id, None) is not None
