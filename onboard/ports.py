"""The onboard node's Zenoh seams with the trackside, for one vehicle.

:class:`TracksidePorts` declares every publisher, subscriber, queryable and liveliness token the
ATO-OB process holds (the key space is ``protocol.registry``'s), and nothing else: what arrives
waits in the subscribers' queues until a task of the node takes it, at a tick of simulated time;
what the node sends goes out through :meth:`TracksidePorts.publish_status`,
:meth:`TracksidePorts.emit` and the other senders. Callbacks run on Zenoh's threads and only
queue or signal.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import zenoh

from protocol import (
    LivelinessWatcher,
    TypedPublisher,
    TypedQueryable,
    TypedSubscriber,
    declare_liveliness,
    request,
    request_async,
)
from protocol import messages as m
from protocol.registry import (
    ALIVE_ONBOARD,
    ALIVE_TRACKSIDE,
    COMMAND,
    EVENT,
    JOURNEY_PROFILE,
    JOURNEY_PROFILE_ACK,
    LINE_DOCUMENT,
    LINE_VERSION,
    MOVEMENT_AUTHORITY,
    MOVEMENT_AUTHORITY_CURRENT,
    SESSION,
    SESSION_TERMINATION,
    SPEED_RESTRICTION,
    STATUS,
    STATUS_ACK,
)

__all__ = ["DOCUMENT_TIMEOUT_S", "SessionReply", "TracksidePorts"]

DOCUMENT_TIMEOUT_S = 10.0
"""How long one ask for a line document waits for its answer [s] (a long line is megabytes)."""

SessionReply = m.SessionAccept | m.SessionReject
"""The trackside's answer to a handshake."""


class TracksidePorts:
    """One vehicle's publishers, subscribers and queryable on an open Zenoh session.

    Parameters
    ----------
    session : zenoh.Session
        The process's open session.
    vehicle_id : str
        The vehicle whose keys are declared.
    on_command : callable
        Answers a trackside command on arrival (on Zenoh's thread): the acknowledgement.
    on_status_ack : callable
        Called once a status acknowledgement is queued (it wakes the lockstep barrier).
    on_trackside_liveliness : callable
        Called with (key, alive) as a trackside's liveliness token comes and goes.
    block_status : bool
        Whether a status report waits under congestion instead of being dropped (lockstep:
        each report in a session waits for its acknowledgement).
    """

    def __init__(
        self,
        session: zenoh.Session,
        vehicle_id: str,
        *,
        on_command: Callable[[dict[str, str], m.Command], m.CommandAck],
        on_status_ack: Callable[[], None],
        on_trackside_liveliness: Callable[[str, bool], None],
        block_status: bool,
    ) -> None:
        self.session = session
        self.vehicle_id = vehicle_id
        self._event_seq = 0
        self._status = TypedPublisher(session, STATUS, block=block_status, vehicle=vehicle_id)
        self._events = TypedPublisher(session, EVENT, vehicle=vehicle_id)
        self._commands = TypedQueryable(session, COMMAND, on_command, vehicle=vehicle_id)
        self.journeys = TypedSubscriber(session, JOURNEY_PROFILE, vehicle=vehicle_id)
        self._journey_acks = TypedPublisher(session, JOURNEY_PROFILE_ACK, vehicle=vehicle_id)
        # One subscriber queues the acknowledgement and then wakes the lockstep barrier, so the
        # barrier never wakes before the acknowledgement can be taken. With two subscribers (one
        # to queue, one to wake), Zenoh ran their callbacks apart: the barrier could wake, the
        # session task find nothing, and the report go unacknowledged past the trackside's
        # response timeout (the session was lost in a fault-free lockstep run).
        self.status_acks = TypedSubscriber(
            session, STATUS_ACK, on_message=lambda _k, _a: on_status_ack(), vehicle=vehicle_id
        )
        self.terminations = TypedSubscriber(session, SESSION_TERMINATION, vehicle=vehicle_id)
        self._termination_out = TypedPublisher(session, SESSION_TERMINATION, vehicle=vehicle_id)
        self.authorities = TypedSubscriber(session, MOVEMENT_AUTHORITY, vehicle=vehicle_id)
        self.restrictions = TypedSubscriber(session, SPEED_RESTRICTION, vehicle=vehicle_id)
        self._tracksides = LivelinessWatcher(
            session, ALIVE_TRACKSIDE.format(instance="*"), on_trackside_liveliness
        )
        self._token = declare_liveliness(session, ALIVE_ONBOARD.format(vehicle=vehicle_id))

    # -- what arrives ----------------------------------------------------------------------------

    def received_journeys(self) -> Iterator[m.JourneyProfile]:
        """The journey profiles queued since the last call, oldest first."""
        while (received := self.journeys.try_recv()) is not None:
            yield received[1]

    def received_authorities(self) -> Iterator[m.MovementAuthorityMessage]:
        """The RBC's movement authorities for this vehicle queued since the last call."""
        while (received := self.authorities.try_recv()) is not None:
            if received[1].vehicle_id == self.vehicle_id:
                yield received[1]

    def received_restrictions(self) -> Iterator[m.SpeedRestrictionMessage]:
        """The RBC's speed restrictions for this vehicle queued since the last call."""
        while (received := self.restrictions.try_recv()) is not None:
            if received[1].vehicle_id == self.vehicle_id:
                yield received[1]

    def received_status_acks(self) -> Iterator[m.StatusAck]:
        while (received := self.status_acks.try_recv()) is not None:
            yield received[1]

    def received_terminations(self) -> Iterator[m.SessionTermination]:
        while (received := self.terminations.try_recv()) is not None:
            yield received[1]

    def subscribers(self) -> tuple[TypedSubscriber[Any], ...]:
        """Every subscriber of the trackside's messages, for their counters."""
        return (
            self.journeys,
            self.status_acks,
            self.terminations,
            self.authorities,
            self.restrictions,
        )

    @property
    def inputs_received(self) -> tuple[int, int, int]:
        """Journey profiles, movement authorities and TSRs received so far."""
        return (
            self.journeys.stats.received,
            self.authorities.stats.received,
            self.restrictions.stats.received,
        )

    @property
    def trackside_seen(self) -> bool:
        """Whether a trackside's liveliness token is seen now."""
        return bool(self._tracksides.alive())

    # -- what goes out ---------------------------------------------------------------------------

    def publish_status(self, report: m.StatusReport) -> None:
        self._status.put(report)

    def acknowledge_journey(self, ack: m.JourneyProfileAck) -> None:
        self._journey_acks.put(ack)

    def terminate(self, termination: m.SessionTermination) -> None:
        self._termination_out.put(termination)

    def emit(self, severity: m.EventSeverity, code: str, text: str, *, at_s: float) -> None:
        """Publish an event for the trackside's log, numbered in the order emitted."""
        self._events.put(
            m.Event(
                vehicle_id=self.vehicle_id,
                seq=self._event_seq,
                sim_time_s=at_s,
                severity=severity,
                code=code,
                text=text,
            )
        )
        self._event_seq += 1

    # -- queries ---------------------------------------------------------------------------------

    def ask_line_version(
        self, line_id: str, on_reply: Callable[[m.LineVersionReply], None]
    ) -> None:
        """Ask which version of the line the trackside holds (answered on Zenoh's thread).

        Raises :class:`~protocol.ProtocolError` if the query cannot be sent."""
        ask = m.LineVersionRequest(vehicle_id=self.vehicle_id, line_id=line_id)
        request_async(self.session, LINE_VERSION, ask, on_reply, line=line_id)

    def ask_line_document(
        self, line_id: str, on_reply: Callable[[m.LineDocumentReply], None]
    ) -> None:
        """Ask the trackside for the line's document (answered on Zenoh's thread).

        Raises :class:`~protocol.ProtocolError` if the query cannot be sent."""
        ask = m.LineDocumentRequest(vehicle_id=self.vehicle_id, line_id=line_id)
        request_async(
            self.session, LINE_DOCUMENT, ask, on_reply, timeout_s=DOCUMENT_TIMEOUT_S, line=line_id
        )

    def ask_session(self, handshake: m.SessionRequest, *, timeout_s: float) -> SessionReply:
        """The handshake's answer, waited for (lockstep).

        Raises :class:`~protocol.RequestTimeoutError` when nobody answers in time and
        :class:`~protocol.ProtocolError` on a bad answer."""
        reply: SessionReply = request(
            self.session, SESSION, handshake, timeout_s=timeout_s, vehicle=self.vehicle_id
        )
        return reply

    def ask_session_async(
        self, handshake: m.SessionRequest, on_reply: Callable[[SessionReply], None]
    ) -> None:
        """The handshake, answered on Zenoh's thread (real time)."""
        request_async(self.session, SESSION, handshake, on_reply, vehicle=self.vehicle_id)

    def ask_current_authority(self, *, timeout_s: float) -> m.MovementAuthorityReply:
        """The RBC's MA and TSRs in force for this vehicle, waited for (lockstep).

        Raises :class:`~protocol.RequestTimeoutError` when nobody answers in time and
        :class:`~protocol.ProtocolError` on a bad answer."""
        ask = m.MovementAuthorityRequest(vehicle_id=self.vehicle_id)
        reply: m.MovementAuthorityReply = request(
            self.session,
            MOVEMENT_AUTHORITY_CURRENT,
            ask,
            timeout_s=timeout_s,
            vehicle=self.vehicle_id,
        )
        return reply

    def ask_current_authority_async(
        self, on_reply: Callable[[m.MovementAuthorityReply], None]
    ) -> None:
        """The RBC's MA and TSRs in force for this vehicle, answered on Zenoh's thread."""
        ask = m.MovementAuthorityRequest(vehicle_id=self.vehicle_id)
        request_async(
            self.session, MOVEMENT_AUTHORITY_CURRENT, ask, on_reply, vehicle=self.vehicle_id
        )

    # -- life cycle ------------------------------------------------------------------------------

    def withdraw(self) -> None:
        """The liveliness token goes first, so that the trackside sees the vehicle leave at once."""
        self._token.undeclare()

    def close(self) -> None:
        self._commands.close()
        for closable in (
            self.journeys,
            self._journey_acks,
            self.status_acks,
            self.terminations,
            self._termination_out,
            self.authorities,
            self.restrictions,
            self._status,
            self._events,
            self._tracksides,
        ):
            closable.close()
