"""The onboard side of the ATO-OB ↔ ATO-TS session, in the spirit of SUBSET-126 (DOMAIN.md §2.3).

A pure state machine driven with explicit times, so that lockstep runs are deterministic; the
node moves its messages over Zenoh.

- **NCE** (no communication established): a handshake request (HSReq) with the supported
  versions is due at once (at start-up, when a session was lost, and when a trackside's
  liveliness token appears: the trackside may have restarted), and otherwise no sooner than
  ``retry_s`` (30 s) after a rejection or an unanswered request, unless a trackside's token
  appeared while that request was out (sent, perhaps, while the link was down): then at once.
- **CSR** (session requested): waiting for the answer. An acceptance (HSAck) brings the trackside's
  response timeout and status-report interval; a rejection (HSRej) its reason. No answer within
  the request timeout counts as a failed attempt.
- **CSE** (session established): status reports (STR) are due every interval, one outstanding at
  a time; the trackside acknowledges each (STRAck). The session is lost when nothing has come
  from the trackside (an acknowledgement or a journey profile) within the response timeout.
- **CST** (session terminated): by either side; a new handshake follows after ``retry_s``.

Stale packets (a counter not newer than the last one taken) and packets for another vehicle are
rejected and counted, never acted upon.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

from onboard.freshness import FreshnessGuard
from protocol import messages as m

__all__ = ["ClientState", "SessionClient", "SessionCounters"]

SUPPORTED_VERSIONS = (1,)
RETRY_S = 30.0
"""HSReq again after at least 30 s (DOMAIN.md §2.3)."""
REQUEST_TIMEOUT_S = 5.0


class ClientState(StrEnum):
    NCE = "no_communication"
    CSR = "requested"
    CSE = "established"
    CST = "terminated"


@dataclass
class SessionCounters:
    accepted: int = 0
    rejected: int = 0
    lost: int = 0
    stale: int = 0
    misaddressed: int = 0


@dataclass
class SessionClient:
    """One vehicle's session with its ATO-TS."""

    vehicle_id: str
    etcs_id: int
    train_length_m: float
    retry_s: float = RETRY_S
    request_timeout_s: float = REQUEST_TIMEOUT_S
    state: ClientState = ClientState.NCE
    trackside_id: str | None = None
    response_timeout_s: float = math.inf
    status_interval_s: float = 0.2
    reject_reason: m.SessionRejectReason | None = None
    counters: SessionCounters = field(default_factory=SessionCounters)
    guard: FreshnessGuard = field(default_factory=FreshnessGuard)
    """Takes the trackside's messages of the session held only (``onboard.freshness``)."""
    _next_request_s: float = 0.0
    _requested_s: float = 0.0
    _last_heard_s: float = 0.0
    _next_status_s: float = 0.0
    _outstanding_seq: int | None = None
    _last_ack_seq: int = -1
    _journey_versions: dict[str, int] = field(default_factory=dict)
    _appeared_while_requested: bool = False
    """A trackside's token came while a request was out: a failure of that request (sent,
    perhaps, while the link was down) is followed by a new one at once, not at the retry."""

    @property
    def established(self) -> bool:
        return self.state is ClientState.CSE

    # -- handshake ---------------------------------------------------------------------------

    def request(self, now_s: float, *, track_data_version: str | None) -> m.SessionRequest | None:
        """The HSReq to send now, if one is due."""
        if self.state in (ClientState.NCE, ClientState.CST) and now_s >= self._next_request_s:
            self.state, self._requested_s = ClientState.CSR, now_s
            self._appeared_while_requested = False
            return m.SessionRequest(
                vehicle_id=self.vehicle_id,
                supported_versions=SUPPORTED_VERSIONS,
                etcs_id=self.etcs_id,
                train_length_m=self.train_length_m,
                track_data_version=track_data_version,
            )
        return None

    def on_response(self, response: m.SessionAccept | m.SessionReject | None, now_s: float) -> None:
        """The trackside's answer to the pending request; ``None`` when the query failed."""
        if self.state is not ClientState.CSR:
            self.counters.stale += 1
            return
        if isinstance(response, m.SessionAccept) and response.version in SUPPORTED_VERSIONS:
            self.state = ClientState.CSE
            self.trackside_id = response.trackside_id
            self.response_timeout_s = response.response_timeout_s
            self.status_interval_s = response.status_interval_s
            self.reject_reason = None
            self.guard.open(response.session_id)
            self._last_heard_s = self._next_status_s = now_s
            self._outstanding_seq = None
            self.counters.accepted += 1
            return
        self.state = ClientState.NCE
        self._next_request_s = self._retry_at(now_s)
        if isinstance(response, m.SessionReject):
            self.reject_reason = response.reason
            self.counters.rejected += 1

    def trackside_appeared(self, now_s: float) -> None:
        """A trackside's liveliness token came (back): without a session, ask for one at once
        rather than at the retry (a restarted trackside answers it)."""
        if self.state in (ClientState.NCE, ClientState.CST):
            self._next_request_s = min(self._next_request_s, now_s)
        elif self.state is ClientState.CSR:
            self._appeared_while_requested = True

    def _retry_at(self, now_s: float) -> float:
        """When to ask again after a failed request: at the retry, or at once when a trackside
        appeared meanwhile."""
        return now_s if self._appeared_while_requested else now_s + self.retry_s

    # -- upkeep ------------------------------------------------------------------------------

    def status_due(self, now_s: float, seq: int) -> bool:
        """Whether to send the status report ``seq`` now: at the interval, and only when the
        previous one has been acknowledged (or the session is not yet established, when
        reports go out for the fleet view at the same interval)."""
        if now_s + 1e-9 < self._next_status_s:
            return False
        if self.established and self._outstanding_seq is not None:
            return False
        self._next_status_s = now_s + self.status_interval_s
        if self.established:
            self._outstanding_seq = seq
        return True

    def on_status_ack(self, vehicle_id: str, seq: int, now_s: float) -> bool:
        """Take an STRAck; False when it is stale, misaddressed or outside a session."""
        if vehicle_id != self.vehicle_id:
            self.counters.misaddressed += 1
            return False
        if not self.established or seq <= self._last_ack_seq:
            self.counters.stale += 1
            return False
        self._last_ack_seq = seq
        if self._outstanding_seq is not None and seq >= self._outstanding_seq:
            self._outstanding_seq = None
        self._last_heard_s = now_s
        return True

    def on_journey_profile(self, profile: m.JourneyProfile, now_s: float) -> bool:
        """Whether to act on a journey profile: addressed to us and newer than the last version
        of the same journey. A profile counts as hearing from the trackside."""
        if profile.vehicle_id != self.vehicle_id:
            self.counters.misaddressed += 1
            return False
        last = self._journey_versions.get(profile.journey_id, -1)
        if profile.version <= last:
            self.counters.stale += 1
            return False
        self._journey_versions[profile.journey_id] = profile.version
        if self.established:
            self._last_heard_s = now_s
        return True

    def step(self, now_s: float) -> bool:
        """Check the timeouts; True when the session has just been lost."""
        if self.state is ClientState.CSR and now_s - self._requested_s > self.request_timeout_s:
            self.state = ClientState.NCE
            self._next_request_s = self._retry_at(now_s)
            return False
        if self.established and now_s - self._last_heard_s > self.response_timeout_s:
            # A lost session is asked for again at once (a trackside that restarted answers
            # it); only a request that fails waits for the retry.
            self.state = ClientState.NCE
            self.guard.close()
            self._next_request_s = now_s
            self._outstanding_seq = None
            self.counters.lost += 1
            return True
        return False

    # -- termination -------------------------------------------------------------------------

    def terminate(self, reason: str, now_s: float) -> m.SessionTermination | None:
        """End the session from the onboard: the SESSTerm to send, if one was open."""
        if not self.established:
            return None
        self.state = ClientState.CST
        self.guard.close()
        self._next_request_s = now_s + self.retry_s
        return m.SessionTermination(vehicle_id=self.vehicle_id, by="onboard", reason=reason)

    def on_termination(self, termination: m.SessionTermination, now_s: float) -> bool:
        """The trackside ended the session (SESSTermReq); False if not for us or not open."""
        if termination.vehicle_id != self.vehicle_id or termination.by != "trackside":
            self.counters.misaddressed += 1
            return False
        if not self.established:
            self.counters.stale += 1
            return False
        self.state = ClientState.CST
        self.guard.close()
        self._next_request_s = now_s + self.retry_s
        return True
