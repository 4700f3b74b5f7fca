"""The trackside's Zenoh side: which vehicles are alive, their latest status, their sessions.

A vehicle is alive while its liveliness token ``ato/alive/ob/{vehicle}`` exists; Zenoh withdraws
the token when the onboard's session closes, or after the link lease (≤ 1 s) when the process
freezes or its link breaks. Vehicles once seen stay listed, as not alive.

The ATO-TS side of the session (``trackside.session``): handshakes are answered on
``ato/ts/session/{vehicle}``, each status report of an open session is acknowledged (STRAck), a
session ends with the vehicle's liveliness, with a termination from either side, or when a
report comes after a gap longer than the response timeout in the onboard's simulated time.
Journey profiles go out with :meth:`ZenohBridge.send_journey_profile`, which waits for the
onboard's acknowledgement (:mod:`trackside.journey_link`).
"""

from __future__ import annotations

import logging
import re
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from protocol import (
    LivelinessWatcher,
    TopicStats,
    TransportError,
    TypedPublisher,
    TypedQueryable,
    TypedSubscriber,
    declare_liveliness,
)
from protocol import messages as m
from protocol.registry import (
    ALIVE_ONBOARD,
    ALIVE_TRACKSIDE,
    EVENT,
    LINE_DOCUMENT,
    LINE_VERSION,
    SESSION,
    SESSION_TERMINATION,
    STATUS,
    STATUS_ACK,
    Topic,
)
from trackside.command_link import send_command, send_command_async
from trackside.journey_link import JourneyProfileLink
from trackside.session import SessionManager

__all__ = ["VehicleSnapshot", "ZenohBridge"]

_log = logging.getLogger(__name__)
_VEHICLE_ID = re.compile(r"[A-Za-z0-9_-]{1,32}")
"""``protocol.messages.VehicleId``'s pattern and length."""

ChangeListener = Callable[[], None]
StatusObserver = Callable[[m.StatusReport], object]
EventObserver = Callable[[m.Event], object]
LineVersionLookup = Callable[[str], str | None]
"""The current version of a line, ``None`` when the trackside does not hold it."""
LineDocumentLookup = Callable[[str], tuple[str, str] | None]
"""The current canonical JSON of a line and its version, ``None`` when the trackside does not
hold it."""


@dataclass(frozen=True)
class VehicleSnapshot:
    id: str
    alive: bool
    status: m.StatusReport | None
    status_age_s: float | None
    status_rate_ok: bool


class ZenohBridge:
    """Subscribes to every vehicle's liveliness and status on an open session."""

    def __init__(
        self,
        session: zenoh.Session,
        *,
        instance_id: str,
        line_version: LineVersionLookup | None = None,
        line_document: LineDocumentLookup | None = None,
        clock: Callable[[], float] = time.monotonic,
        sessions: SessionManager | None = None,
        status_intake_s: float | None = None,
    ) -> None:
        """``status_intake_s``: the status reports taken in batches, at most one a period
        (:class:`~protocol.bus.TypedSubscriber`); ``None``, each on arrival (lockstep runs)."""
        self._clock = clock
        self._zenoh = session
        self.sessions = sessions or SessionManager(trackside_id=instance_id)
        self._session_lock = threading.Lock()
        self._closed = False
        """Set by :meth:`close`: a callback still in flight then publishes nothing."""
        self._publishers: dict[tuple[str, str], TypedPublisher[Any]] = {}
        self._lock = threading.Lock()
        self._known: set[str] = set()
        self.bad_liveliness = 0
        """Liveliness tokens under ``ato/alive/ob/`` whose last chunk is not a vehicle id."""
        self._alive: set[str] = set()
        self._listeners: list[ChangeListener] = []
        self._status_observers: list[StatusObserver] = []
        self._report_supervisor: StatusObserver | None = None
        self._event_observers: list[EventObserver] = []
        self._status = TypedSubscriber(
            session, STATUS, on_message=self._on_status, clock=clock, drain_period_s=status_intake_s
        )
        self._liveliness = LivelinessWatcher(
            session, ALIVE_ONBOARD.format(vehicle="*"), self._on_liveliness
        )
        self._line_version = line_version
        self._line_versions = TypedQueryable(session, LINE_VERSION, self._answer_line_version)
        self.line_document = line_document
        """Where line documents are read (the service's database); replaceable (a test injects
        a corrupted transfer through it)."""
        self._line_documents = TypedQueryable(session, LINE_DOCUMENT, self._answer_line_document)
        self._handshakes = TypedQueryable(session, SESSION, self._answer_session)
        self._terminations = TypedSubscriber(
            session, SESSION_TERMINATION, on_message=self._on_termination, vehicle="*"
        )
        self._journeys = JourneyProfileLink(session, publisher=self._publisher, seal=self.seal)
        self._events = TypedSubscriber(
            session, EVENT, on_message=self._on_event, max_queue=1, vehicle="*"
        )
        self._token = declare_liveliness(session, ALIVE_TRACKSIDE.format(instance=instance_id))

    def _answer_line_version(
        self, chunks: dict[str, str], request: m.LineVersionRequest
    ) -> m.LineVersionReply:
        if request.line_id != chunks["line"]:
            raise ValueError(f"request for {request.line_id} sent on {chunks['line']}'s key")
        version = None if self._line_version is None else self._line_version(request.line_id)
        return m.LineVersionReply(line_id=request.line_id, version=version)

    def _answer_line_document(
        self, chunks: dict[str, str], request: m.LineDocumentRequest
    ) -> m.LineDocumentReply:
        """A line's track data for an onboard that lacks them (read on Zenoh's thread)."""
        if request.line_id != chunks["line"]:
            raise ValueError(f"request for {request.line_id} sent on {chunks['line']}'s key")
        lookup = self.line_document
        found = None if lookup is None else lookup(request.line_id)
        if found is None:
            return m.LineDocumentReply(line_id=request.line_id)
        document, version = found
        _log.info("line %s (%s) sent to %s", request.line_id, version[:12], request.vehicle_id)
        return m.LineDocumentReply(line_id=request.line_id, version=version, document=document)

    @property
    def status_stats(self) -> object:
        return self._status.stats

    def topic_stats(self) -> dict[str, TopicStats]:
        """Each subscribed topic's counters (received, bad payloads, queue overflows)."""
        subscribers = (self._status, self._events, self._terminations)
        stats = {subscriber.topic.name: subscriber.stats for subscriber in subscribers}
        return stats | {self._journeys.topic_name: self._journeys.stats}

    def add_listener(self, listener: ChangeListener) -> None:
        with self._lock:
            self._listeners.append(listener)

    def remove_listener(self, listener: ChangeListener) -> None:
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)

    def observe(
        self, *, status: StatusObserver | None = None, event: EventObserver | None = None
    ) -> None:
        """Call ``status`` with every status report and ``event`` with every event whose key
        names its own vehicle, on Zenoh's thread: observers must not block."""
        with self._lock:
            if status is not None:
                self._status_observers.append(status)
            if event is not None:
                self._event_observers.append(event)

    def supervise_reports(self, supervisor: StatusObserver) -> None:
        """Call ``supervisor`` with every report of an open session before it is acknowledged
        (on Zenoh's thread): the RBC's separation, whose changes must go out first."""
        self._report_supervisor = supervisor

    def _on_event(self, key: str, event: m.Event) -> None:
        if event.vehicle_id != EVENT.parse(key)["vehicle"]:
            return
        with self._lock:
            observers = list(self._event_observers)
        for observer in observers:
            observer(event)

    def _notify(self) -> None:
        with self._lock:
            listeners = list(self._listeners)
        for listener in listeners:
            listener()

    def _on_liveliness(self, key: str, alive: bool) -> None:
        vehicle = key.rsplit("/", 1)[-1]
        if not _VEHICLE_ID.fullmatch(vehicle):
            # Not a vehicle id (a misconfigured or hostile peer): counted and dropped, so that
            # one bad token cannot break the fleet view.
            self.bad_liveliness += 1
            _log.warning("liveliness token %r is not a vehicle's: ignored", key)
            return
        with self._lock:
            self._known.add(vehicle)
            if alive:
                self._alive.add(vehicle)
            else:
                self._alive.discard(vehicle)
        if not alive:
            self._status.forget(STATUS.key(vehicle=vehicle))
            with self._session_lock:
                self.sessions.close(vehicle)
        self._notify()

    def _on_status(self, key: str, report: m.StatusReport) -> None:
        if report.vehicle_id == STATUS.parse(key)["vehicle"]:
            with self._session_lock:
                ack = self.sessions.on_status(report, report.sim_time_s)
            supervisor = self._report_supervisor
            if ack is not None and supervisor is not None:
                # Before the acknowledgement: what the report changes (an MA of the train
                # behind) is published ahead of it, so a lockstep onboard that waits for the
                # acknowledgement has it by then.
                supervisor(report)
            if ack is not None:
                try:
                    self._publisher(STATUS_ACK, report.vehicle_id).put(ack)
                except TransportError:
                    if not self._closed:
                        raise
                    return  # a report that arrived while the bridge closed: no one to answer
            with self._lock:
                observers = list(self._status_observers)
            for observer in observers:
                observer(report)
        self._notify()

    # -- session -------------------------------------------------------------------------------

    def _publisher(self, topic: Topic[Any], vehicle_id: str) -> TypedPublisher[Any]:
        """One publisher per topic and vehicle, declared at first use."""
        with self._session_lock:
            publisher = self._publishers.get((topic.name, vehicle_id))
            if publisher is None:
                publisher = TypedPublisher(self._zenoh, topic, vehicle=vehicle_id)
                self._publishers[(topic.name, vehicle_id)] = publisher
        return publisher

    def _answer_session(
        self, chunks: dict[str, str], request: m.SessionRequest
    ) -> m.SessionAccept | m.SessionReject:
        if request.vehicle_id != chunks["vehicle"]:
            raise ValueError(f"handshake of {request.vehicle_id} on {chunks['vehicle']}'s key")
        snapshot = self.snapshot(request.vehicle_id)
        now = 0.0 if snapshot is None or snapshot.status is None else snapshot.status.sim_time_s
        with self._session_lock:
            answer = self.sessions.on_request(request, now)
        self._notify()
        return answer

    def _on_termination(self, key: str, termination: m.SessionTermination) -> None:
        if termination.vehicle_id == SESSION_TERMINATION.parse(key)["vehicle"]:
            with self._session_lock:
                self.sessions.on_termination(termination)
            self._notify()

    def seal(self, vehicle_id: str) -> m.Freshness | None:
        """The session id and next number for a message to the vehicle (``None``: no session,
        the onboard will refuse it)."""
        return self.sessions.seal(vehicle_id)

    def session_open(self, vehicle_id: str) -> bool:
        with self._session_lock:
            return vehicle_id in self.sessions.sessions

    def train_length_m(self, vehicle_id: str) -> float | None:
        """The train's length from its open session's handshake [m]; None without one."""
        with self._session_lock:
            session = self.sessions.sessions.get(vehicle_id)
            return None if session is None else session.train_length_m

    def terminate_session(self, vehicle_id: str, reason: str) -> bool:
        """End a vehicle's session from the trackside (SESSTermReq)."""
        with self._session_lock:
            termination = self.sessions.terminate(vehicle_id, reason)
        if termination is None:
            return False
        self._publisher(SESSION_TERMINATION, vehicle_id).put(termination)
        self._notify()
        return True

    # -- journey profiles ----------------------------------------------------------------------

    def send_journey_profile(
        self, profile: m.JourneyProfile, *, timeout_s: float = 5.0
    ) -> m.JourneyProfileAck | None:
        """Send a journey profile and wait for its acknowledgement (or rejection); ``None``
        when none came within ``timeout_s`` of wall time (:class:`JourneyProfileLink`)."""
        return self._journeys.send(profile, timeout_s=timeout_s)

    # -- commands ------------------------------------------------------------------------------

    def command(self, command: m.Command, *, timeout_s: float) -> m.CommandAck:
        """Send a command, sealed for the vehicle's session, and wait for the vehicle's
        acknowledgement (:func:`trackside.command_link.send_command`)."""
        return send_command(self._zenoh, self._sealed(command), timeout_s=timeout_s)

    def _sealed(self, command: m.Command) -> m.Command:
        return command.model_copy(update={"freshness": self.seal(command.vehicle_id)})

    def command_async(
        self,
        command: m.Command,
        on_done: Callable[[m.CommandAck | None], None],
        *,
        timeout_s: float,
    ) -> None:
        """Send a command, sealed, without waiting
        (:func:`trackside.command_link.send_command_async`)."""
        send_command_async(self._zenoh, self._sealed(command), on_done, timeout_s=timeout_s)

    def vehicle_ids(self) -> list[str]:
        with self._lock:
            return sorted(self._known)

    def snapshot(self, vehicle_id: str) -> VehicleSnapshot | None:
        with self._lock:
            if vehicle_id not in self._known:
                return None
            alive = vehicle_id in self._alive
        key = STATUS.key(vehicle=vehicle_id)
        monitor = self._status.monitor
        last = monitor.last_seen(key)
        seen = None if last is None else (last, monitor.rate_ok(key))
        return _snapshot(vehicle_id, alive, self._status.latest(key), seen, self._clock())

    def fleet(self) -> list[VehicleSnapshot]:
        """Every vehicle seen, in its id's order: :meth:`snapshot` of each, at one instant, read
        in one pass (the list of a thousand vehicles is asked five times a second)."""
        with self._lock:
            known = sorted(self._known)
            alive = set(self._alive)
        now = self._clock()
        latest = self._status.latest_all()
        health = self._status.monitor.health(now)
        snapshots = []
        for vehicle in known:
            key = STATUS.key(vehicle=vehicle)
            status = latest.get(key)
            snapshots.append(_snapshot(vehicle, vehicle in alive, status, health.get(key), now))
        return snapshots

    def close(self) -> None:
        self._closed = True
        self._token.undeclare()
        # The subscribers first, so that their callbacks stop before the publishers they use go.
        self._events.close()
        self._handshakes.close()
        self._terminations.close()
        self._journeys.close()
        self._line_versions.close()
        self._line_documents.close()
        self._liveliness.close()
        self._status.close()
        with self._session_lock:
            publishers = list(self._publishers.values())
        for publisher in publishers:
            publisher.close()


def _snapshot(
    vehicle_id: str,
    alive: bool,
    status: m.StatusReport | None,
    seen: tuple[float, bool] | None,
    now: float,
) -> VehicleSnapshot:
    """A vehicle's snapshot from its latest report and ``seen``: the report's arrival time and
    whether its rate is right (``None`` before the first). A dead vehicle shows no status, nor
    a report published under another vehicle's key (not trusted)."""
    if not alive or (status is not None and status.vehicle_id != vehicle_id):
        status = None
    last, rate_ok = seen if seen is not None else (None, False)
    return VehicleSnapshot(
        id=vehicle_id,
        alive=alive,
        status=status,
        status_age_s=None if last is None or status is None else now - last,
        status_rate_ok=alive and rate_ok,
    )
