"""What the RBC emulator remembers: each vehicle's MA in force, its counter, its acknowledgement,
its TSRs in force.

:class:`MovementAuthorityStore` is the state behind :class:`trackside.rbc.RbcEmulator`: the
current movement authority (MA) of every vehicle, the last ``ma_id`` sent to it (revocations
too), the onboard's latest acknowledgement, the temporary speed restrictions (TSRs) in force for
it, and the listeners told of every change. In the service it is filled, at start-up, from what
the database kept (:mod:`trackside.rbc_persistence`). The
emulator checks and publishes a change, then records it here; the Zenoh link
(:mod:`trackside.rbc_link`) reads it to answer ``current_ma`` and records acknowledgements.

Every method takes one short lock, so that readers on other threads (REST, Zenoh's callbacks)
never wait for a publication in progress.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from protocol import messages as m

__all__ = ["MaListener", "MovementAuthorityStore"]

MaListener = Callable[[m.MovementAuthorityMessage], None]
"""Called with each MA message after it was sent and stored."""

# The emulator's own logger, as before the RBC was split into modules: log filters name it.
_log = logging.getLogger("trackside.rbc")


class MovementAuthorityStore:
    """Each vehicle's MA in force, its ``ma_id`` counter and its latest acknowledgement."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._current: dict[str, m.MovementAuthorityMessage] = {}
        self._last_ma_id: dict[str, int] = {}
        self._acknowledgements: dict[str, m.MovementAuthorityAck] = {}
        self._restrictions: dict[str, dict[str, m.SpeedRestrictionMessage]] = {}
        self._listeners: list[MaListener] = []

    def restore(
        self,
        last_ma_ids: dict[str, int],
        current: dict[str, m.MovementAuthorityMessage],
        restrictions: dict[str, dict[str, m.SpeedRestrictionMessage]],
    ) -> None:
        """Take back what was kept across a restart (before anything is sent)."""
        with self._lock:
            self._last_ma_id.update(last_ma_ids)
            self._current.update(current)
            for vehicle_id, in_force in restrictions.items():
                self._restrictions.setdefault(vehicle_id, {}).update(in_force)

    def restrictions(self, vehicle_id: str) -> tuple[m.SpeedRestrictionMessage, ...]:
        """The TSRs in force for the vehicle, in the order they were put in force."""
        with self._lock:
            return tuple(self._restrictions.get(vehicle_id, {}).values())

    def record_restriction(self, message: m.SpeedRestrictionMessage) -> None:
        """Store a TSR already sent: put in force, or (no speed) revoked."""
        with self._lock:
            in_force = self._restrictions.setdefault(message.vehicle_id, {})
            in_force.pop(message.restriction_id, None)
            if message.speed_mps is not None:
                in_force[message.restriction_id] = message

    def current(self, vehicle_id: str) -> m.MovementAuthorityMessage | None:
        """The vehicle's MA in force (issued, extended or shortened); ``None`` if none."""
        with self._lock:
            return self._current.get(vehicle_id)

    def last_ma_id(self, vehicle_id: str) -> int:
        """The id of the last MA message sent to the vehicle (revocations too); 0 if none."""
        with self._lock:
            return self._last_ma_id.get(vehicle_id, 0)

    def acknowledgement(self, vehicle_id: str) -> m.MovementAuthorityAck | None:
        """The vehicle's latest acknowledgement of one of its MAs, if any arrived."""
        with self._lock:
            return self._acknowledgements.get(vehicle_id)

    def vehicle_ids(self) -> list[str]:
        """The vehicles that were ever sent an MA."""
        with self._lock:
            return sorted(self._last_ma_id)

    def add_listener(self, listener: MaListener) -> None:
        """Call ``listener(message)`` after each recorded change, on the recording thread."""
        with self._lock:
            self._listeners.append(listener)

    def remove_listener(self, listener: MaListener) -> None:
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)

    def record(self, message: m.MovementAuthorityMessage) -> None:
        """Store a change already sent, then tell the listeners.

        A revocation (no ``authority``) leaves the vehicle without an MA in force; every change
        moves its counter to the message's ``ma_id``.
        """
        vehicle_id = message.vehicle_id
        with self._lock:
            self._last_ma_id[vehicle_id] = message.ma_id
            if message.authority is None:
                self._current.pop(vehicle_id, None)
            else:
                self._current[vehicle_id] = message
            listeners = list(self._listeners)
        for listener in listeners:
            try:
                listener(message)
            except Exception:  # a listener's bug must not undo a change already sent
                _log.exception("MA listener failed on %s ma_id %d", vehicle_id, message.ma_id)

    def record_acknowledgement(self, vehicle_id: str, ack: m.MovementAuthorityAck) -> None:
        """Keep the vehicle's acknowledgement if it is its latest; drop one of an unsent MA."""
        with self._lock:
            if ack.ma_id > self._last_ma_id.get(vehicle_id, 0):
                _log.warning("dropped %s's ack of ma_id %d, never sent", vehicle_id, ack.ma_id)
                return
            previous = self._acknowledgements.get(vehicle_id)
            if previous is None or ack.ma_id >= previous.ma_id:
                self._acknowledgements[vehicle_id] = ack
