"""The RBC emulator's Zenoh side: MAs and TSRs out, ``current_ma`` answers and acknowledgements in.

:class:`RbcZenohLink` is what :class:`trackside.rbc.RbcEmulator` holds when it has a Zenoh
session. It declares one publisher per vehicle on ``ato/ts/rbc/{vehicle}/ma`` and on
``ato/ts/rbc/{vehicle}/tsr`` (reliable FIFO, both), the first time the vehicle is sent one; it
answers ``ato/ts/rbc/{vehicle}/current_ma`` from the emulator's
:class:`~trackside.rbc_store.MovementAuthorityStore`; and it hands the onboard's
acknowledgements from ``ato/ob/{vehicle}/ma_ack`` to that store.

Every message is sealed as it goes out (``seal``: the session's id and its next number, see
:mod:`trackside.session`), the answers to ``current_ma`` too: the onboard takes only what belongs
to the session it holds.

Zenoh's failure to publish (:class:`protocol.TransportError`) comes out as the RBC's own
:class:`~trackside.errors.RbcPublicationError`. The emulator serialises its changes, and calls
the publishing methods and :meth:`RbcZenohLink.close_publishers` with its change lock held;
the callbacks run on Zenoh's threads and touch only the store.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TypeVar

import zenoh

from protocol import TransportError, TypedPublisher, TypedQueryable, TypedSubscriber
from protocol import messages as m
from protocol.registry import (
    MOVEMENT_AUTHORITY,
    MOVEMENT_AUTHORITY_ACK,
    MOVEMENT_AUTHORITY_CURRENT,
    SPEED_RESTRICTION,
)
from trackside.errors import RbcPublicationError
from trackside.rbc_store import MovementAuthorityStore

__all__ = ["RbcZenohLink", "Seal"]

_Sealed = TypeVar("_Sealed", m.MovementAuthorityMessage, m.SpeedRestrictionMessage)

Seal = Callable[[str], m.Freshness | None]
"""The session's id and next number for a message to the vehicle (``None``: no session)."""

# The emulator's own logger, as before the RBC was split into modules: log filters name it.
_log = logging.getLogger("trackside.rbc")


class RbcZenohLink:
    """The RBC's publishers, its ``current_ma`` queryable and its acknowledgement subscriber.

    Parameters
    ----------
    session
        The Zenoh session to publish on and answer queries from.
    store
        Where the MAs in force are read and the acknowledgements recorded.
    seal
        Seals each message for its vehicle's session; none: sent unsealed (refused on board).
    """

    def __init__(
        self, session: zenoh.Session, store: MovementAuthorityStore, seal: Seal | None = None
    ) -> None:
        self._session = session
        self._store = store
        self._seal = seal
        self._publishers: dict[str, TypedPublisher[m.MovementAuthorityMessage]] = {}
        self._tsr_publishers: dict[str, TypedPublisher[m.SpeedRestrictionMessage]] = {}
        self._queryable = TypedQueryable(session, MOVEMENT_AUTHORITY_CURRENT, self._answer_current)
        try:
            self._acks = TypedSubscriber(
                session, MOVEMENT_AUTHORITY_ACK, on_message=self._on_acknowledgement
            )
        except Exception:
            self._queryable.close()
            raise

    def publish_movement_authority(self, message: m.MovementAuthorityMessage) -> None:
        """Send an MA change on its vehicle's key.

        Raises
        ------
        RbcPublicationError
            If Zenoh could not publish it.
        """
        vehicle_id = message.vehicle_id
        with _publication():
            publisher = self._publishers.get(vehicle_id)
            if publisher is None:
                publisher = TypedPublisher(self._session, MOVEMENT_AUTHORITY, vehicle=vehicle_id)
                self._publishers[vehicle_id] = publisher
            publisher.put(self._sealed(message))

    def publish_speed_restriction(
        self, vehicle_id: str, message: m.SpeedRestrictionMessage
    ) -> None:
        """Send a TSR (or its revocation) on the vehicle's key.

        Raises
        ------
        RbcPublicationError
            If Zenoh could not publish it.
        """
        with _publication():
            publisher = self._tsr_publishers.get(vehicle_id)
            if publisher is None:
                publisher = TypedPublisher(self._session, SPEED_RESTRICTION, vehicle=vehicle_id)
                self._tsr_publishers[vehicle_id] = publisher
            publisher.put(self._sealed(message))

    def close_publishers(self) -> None:
        """Undeclare every vehicle's publishers (called with the emulator's change lock held)."""
        for publisher in self._publishers.values():
            publisher.close()
        self._publishers.clear()
        for tsr_publisher in self._tsr_publishers.values():
            tsr_publisher.close()
        self._tsr_publishers.clear()

    def close_subscriptions(self) -> None:
        """Stop taking acknowledgements and answering ``current_ma``."""
        self._acks.close()
        self._queryable.close()

    def _answer_current(
        self, chunks: dict[str, str], request: m.MovementAuthorityRequest
    ) -> m.MovementAuthorityReply:
        vehicle_id = chunks["vehicle"]
        if request.vehicle_id != vehicle_id:
            raise ValueError(f"request for {request.vehicle_id} sent on {vehicle_id}'s key")
        current = self._store.current(vehicle_id)
        return m.MovementAuthorityReply(
            vehicle_id=vehicle_id,
            movement_authority=None if current is None else self._sealed(current),
            speed_restrictions=tuple(
                self._sealed(tsr) for tsr in self._store.restrictions(vehicle_id)
            ),
        )

    def _sealed(self, message: _Sealed) -> _Sealed:
        seal = None if self._seal is None else self._seal(message.vehicle_id)
        return message.model_copy(update={"freshness": seal})

    def _on_acknowledgement(self, key: str, ack: m.MovementAuthorityAck) -> None:
        vehicle_id = MOVEMENT_AUTHORITY_ACK.parse(key)["vehicle"]
        if ack.vehicle_id != vehicle_id:
            _log.warning("dropped an MA ack of %s sent on %s's key", ack.vehicle_id, vehicle_id)
            return
        self._store.record_acknowledgement(vehicle_id, ack)


@contextmanager
def _publication() -> Iterator[None]:
    """Zenoh's failure to publish, as the RBC's own error (nothing was changed)."""
    try:
        yield
    except TransportError as exc:
        raise RbcPublicationError(f"the MA could not be published, nothing changed: {exc}") from exc
