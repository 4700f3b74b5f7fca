"""What the trackside sent, taken on board at the ``commands`` tick: journey profiles, the RBC's
movement authorities and speed restrictions (the line's version and track data are taken by
``onboard.track_desk`` at the same tick, just before).

Messages wait in the ports' queues (and the RBC's current MA's answers in
:class:`TracksideIntake`) until :meth:`TracksideIntake.take`, so that what they change
happens at a tick of simulated time. A journey profile, an MA or a TSR is taken only when it is
fresh (the session held, a number not taken before: ``onboard.freshness``); an MA only when it
is newer than the last one taken (``ma_id``). Each is handed to the onboard stack and logged as
an event; what is refused is logged with its reason, never raised.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable

from onboard.etcs import EtcsError
from onboard.ports import TracksidePorts
from onboard.runtime.clock import NS_PER_S
from onboard.session import SessionClient
from onboard.session_link import Emit
from onboard.stack import OnboardStack
from protocol import messages as m

__all__ = ["TracksideIntake"]

_INFO, _WARNING = m.EventSeverity.INFO, m.EventSeverity.WARNING


class TracksideIntake:
    """Hands the trackside's messages to the stack at the tick they are taken."""

    def __init__(
        self, ports: TracksidePorts, stack: OnboardStack, client: SessionClient, *, emit: Emit
    ) -> None:
        self.ports = ports
        self.stack = stack
        self.client = client
        self._emit = emit
        self._current: list[m.MovementAuthorityReply] = []
        self._lock = threading.Lock()
        self.last_ma_id = 0
        """The ``ma_id`` of the last RBC message taken (0: none yet)."""

    def on_current_authority(self, reply: m.MovementAuthorityReply) -> None:
        """The RBC's MA and TSRs in force (on Zenoh's thread, or the node's in lockstep): taken
        at the next :meth:`take`, as if they had just been sent."""
        if reply.vehicle_id != self.ports.vehicle_id:
            return
        with self._lock:
            self._current.append(reply)

    def take(self, now_ns: int) -> None:
        """The journey profiles, the MAs and the TSRs received, in that order (the RBC's
        current ones first). The line's version and document are the track-data desk's
        (``onboard.track_desk``), taken just before."""
        self._take_journeys(now_ns)
        with self._lock:
            current, self._current = self._current, []
        authorities = [r.movement_authority for r in current if r.movement_authority is not None]
        restrictions = [tsr for reply in current for tsr in reply.speed_restrictions]
        self._take_authorities([*authorities, *self.ports.received_authorities()], now_ns)
        self._take_speed_restrictions([*restrictions, *self.ports.received_restrictions()], now_ns)

    def _fresh(self, freshness: m.Freshness | None, what: str, now_ns: int) -> bool:
        """Whether the message is of the session held and new (else logged as refused)."""
        refusal = self.client.guard.admit(freshness)
        if refusal is not None:
            self._emit(_WARNING, "session.refused", f"{what} refused: {refusal.value}", now_ns)
        return refusal is None

    def _take_journeys(self, now_ns: int) -> None:
        now_s = now_ns / NS_PER_S
        for profile in self.ports.received_journeys():
            what = f"journey {profile.journey_id} v{profile.version}"
            if not self._fresh(profile.freshness, what, now_ns):
                continue
            if not self.client.on_journey_profile(profile, now_s):
                self._emit(_WARNING, "journey.stale", f"{what} dropped", now_ns)
                continue
            accepted, reason = self.stack.review_journey(profile)
            self.ports.acknowledge_journey(
                m.JourneyProfileAck(
                    vehicle_id=self.ports.vehicle_id,
                    journey_id=profile.journey_id,
                    version=profile.version,
                    accepted=accepted,
                    reason=reason,
                )
            )
            if accepted:
                self._emit(_INFO, "journey.accepted", f"{what} accepted", now_ns)
            else:
                self._emit(_WARNING, "journey.refused", f"{what} refused: {reason}", now_ns)

    def _take_authorities(
        self, messages: Iterable[m.MovementAuthorityMessage], now_ns: int
    ) -> None:
        for message in messages:
            what = f"MA {message.ma_id}"
            if not self._fresh(message.freshness, what, now_ns):
                continue
            if message.ma_id <= self.last_ma_id:
                # Sent again (the RBC's answer at a new session) or overtaken by a newer one.
                if message.ma_id < self.last_ma_id:
                    self._emit(
                        _WARNING, "etcs.ma_stale", f"{what} older than the MA in force", now_ns
                    )
                continue
            try:
                done = self.stack.receive_movement_authority(message, now_ns / NS_PER_S)
            except EtcsError as exc:
                self._emit(_WARNING, "etcs.ma_refused", str(exc), now_ns)
                continue
            self.last_ma_id = message.ma_id
            self._emit(_INFO, "etcs.ma", f"{what} {done}", now_ns)

    def _take_speed_restrictions(
        self, messages: Iterable[m.SpeedRestrictionMessage], now_ns: int
    ) -> None:
        for message in messages:
            if not self._fresh(message.freshness, f"TSR {message.restriction_id}", now_ns):
                continue
            try:
                what = self.stack.receive_speed_restriction(message, now_ns / NS_PER_S)
            except ValueError as exc:
                self._emit(_WARNING, "etcs.tsr_refused", str(exc), now_ns)
                continue
            self._emit(_INFO, "etcs.tsr", what, now_ns)
