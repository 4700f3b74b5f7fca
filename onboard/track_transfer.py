"""Track data from the trackside: the transfer of seed 000's Track Database Manager.

SUBSET-126's segment profiles in spirit, whole lines here: when the onboard's version of its
line differs from the trackside's, it asks the trackside for the line
(``ato/ts/line/{line}/document``), checks the document's SHA-256 against the version announced
(:func:`onboard.track_store.verified_line`), stores it (:class:`~onboard.track_store.
TrackDataStore`, when the process keeps copies) and holds it as the *pending* track data until
the switch is allowed (:func:`switch_refusal`: at standstill for a while, ATO not engaged). A
document that fails its check is refused, counted and reported; the track data in use stay.

:class:`TrackDataTransfer` holds that state and turns each step into events for the log; the
node asks, hands it the replies at its ``commands`` tick, and switches its parts when
:meth:`TrackDataTransfer.due` gives a line (``onboard.node``). :func:`fetch_line` is the start-up
of a process with no copy: it waits for a trackside to give the line.
"""

from __future__ import annotations

import logging
import threading

import zenoh

from onboard._exceptions import (
    TrackDataCorruptError,
    TrackDataUnavailableError,
)
from onboard.events import StackEvent
from onboard.ports import DOCUMENT_TIMEOUT_S
from onboard.track_store import TrackDataStore, verified_line
from protocol import ProtocolError, request
from protocol import messages as m
from protocol.registry import LINE_DOCUMENT
from trackdb import Line, TrackMap

__all__ = [
    "FETCH_RETRY_S",
    "STANDSTILL_HOLD_S",
    "STANDSTILL_MPS",
    "TrackDataTransfer",
    "fetch_line",
    "switch_refusal",
]

_log = logging.getLogger(__name__)
_INFO, _WARNING = m.EventSeverity.INFO, m.EventSeverity.WARNING

STANDSTILL_MPS = 0.01
"""Below this estimated speed [m/s] the train is at standstill (the stack's own threshold)."""
STANDSTILL_HOLD_S = 2.0
"""How long the train must have stood still before the switch [s]. The fused estimate reaches
zero a little before the train has stopped (a train braking to a stop was still creeping at
5 cm/s when its estimate first read zero): both ETCS's odometry and the fused estimate must
read standstill, and keep reading it this long."""
FETCH_RETRY_S = 1.0
"""Wall time between two asks for the line at start-up [s]."""


def switch_refusal(*, standstill_for_s: float | None, ato_engaged: bool) -> str | None:
    """Why the onboard may not switch to new track data now (None: it may), the train at
    standstill for ``standstill_for_s`` [s] (None: moving).

    The switch happens at standstill only (held :data:`STANDSTILL_HOLD_S`): every part that
    reads the line then takes the new one between two cycles with the train not moving, so no
    supervision, plan or estimate ever spans two versions while the train runs. An engaged ATO
    drives a journey planned on the old version: it is disengaged first (at the end of the
    journey, or by the operator).
    """
    if standstill_for_s is None:
        return "moving"
    if standstill_for_s < STANDSTILL_HOLD_S:
        return f"moving until {STANDSTILL_HOLD_S:g} s at standstill ({standstill_for_s:.1f} s)"
    if ato_engaged:
        return "ATO engaged on a journey planned on the track data in use"
    return None


class TrackDataTransfer:
    """Asks for, verifies, stores and holds new track data of one line until the switch.

    Parameters
    ----------
    line_id : str
        The line the vehicle runs on.
    store : TrackDataStore, optional
        Where verified copies are kept (None: in memory only, as in scenario runs).
    """

    def __init__(self, line_id: str, store: TrackDataStore | None = None) -> None:
        self.line_id = line_id
        self.store = store
        self.pending: TrackMap | None = None
        """Verified track data of a newer version, waiting for the switch."""
        self.received = 0
        """Documents received and verified."""
        self.refused = 0
        """Documents refused: SHA-256 mismatch, invalid, another line."""
        self.switches = 0
        self._replies: list[m.LineDocumentReply] = []
        self._lock = threading.Lock()
        self._asked_for: str | None = None
        self._deferred_for: tuple[str, str] | None = None
        self._standstill_since_s: float | None = None

    # -- asking ----------------------------------------------------------------------------------

    def wanted(self, *, onboard_version: str, trackside_version: str | None) -> str | None:
        """The version to ask the line for now (None: none): the trackside holds another
        version, not pending already, and not asked for since the last :meth:`retry`."""
        if trackside_version is None or trackside_version == onboard_version:
            return None
        if self.pending is not None and self.pending.version == trackside_version:
            return None
        return None if self._asked_for == trackside_version else trackside_version

    def forget_stale(self, trackside_version: str | None) -> StackEvent | None:
        """Drop the pending track data if the trackside now holds another version (a newer
        one is asked for; the one in use, if it went back): never switch to a version the
        trackside no longer holds. What to report."""
        pending = self.pending
        if pending is None or trackside_version in (None, pending.version):
            return None
        self.pending = None
        text = f"{pending.version} no longer the trackside's ({trackside_version}): not used"
        return StackEvent(_WARNING, "track_data.pending_dropped", text)

    def asked(self, version: str) -> None:
        """An ask for ``version`` went out (not repeated until its answer or :meth:`retry`)."""
        self._asked_for = version

    def retry(self) -> None:
        """Forget the asks in flight (each track-data period: an answer lost is asked again)."""
        self._asked_for = None

    def on_reply(self, reply: m.LineDocumentReply) -> None:
        """A reply, on Zenoh's thread: taken at the next :meth:`take`."""
        with self._lock:
            self._replies.append(reply)

    # -- taking ----------------------------------------------------------------------------------

    def take(self, onboard_version: str) -> list[StackEvent]:
        """Check the replies received since the last call: each verified one becomes the
        pending track data (stored first); each other is refused. The events, oldest first."""
        with self._lock:
            replies, self._replies = self._replies, []
        events: list[StackEvent] = []
        for reply in replies:
            event = self._take_one(reply, onboard_version)
            if event is not None:
                events.append(event)
        return events

    def _take_one(self, reply: m.LineDocumentReply, onboard_version: str) -> StackEvent | None:
        self._asked_for = None
        if reply.line_id != self.line_id:
            return None
        if reply.version is None or reply.document is None:
            return StackEvent(_WARNING, "track_data.unavailable", f"trackside lacks {self.line_id}")
        if reply.version == onboard_version or (
            self.pending is not None and self.pending.version == reply.version
        ):
            return None  # an answer to an ask repeated: already held
        try:
            line = self._verify_and_store(reply.document, reply.version)
        except TrackDataCorruptError as exc:
            self.refused += 1
            return StackEvent(_WARNING, "track_data.refused", f"{exc}; the track data in use stay")
        except OSError as exc:
            self.refused += 1
            return StackEvent(_WARNING, "track_data.refused", f"{self.line_id} not stored: {exc}")
        self.pending = TrackMap(line)
        self.received += 1
        return StackEvent(
            _INFO,
            "track_data.received",
            f"{self.line_id} {reply.version} received and verified (SHA-256)",
        )

    def _verify_and_store(self, document: str, version: str) -> Line:
        if self.store is None:
            return verified_line(document, line_id=self.line_id, version=version)
        return self.store.save(document, line_id=self.line_id, version=version)

    # -- switching -------------------------------------------------------------------------------

    def due(
        self, now_s: float, *, standstill: bool, ato_engaged: bool
    ) -> tuple[TrackMap | None, StackEvent | None]:
        """The pending track data if the switch is allowed at ``now_s`` [s] (then no longer
        pending), else None; and the deferral to report (once per version and reason).
        ``standstill``: whether the train reads standstill now (called at every tick)."""
        if not standstill:
            self._standstill_since_s = None
        elif self._standstill_since_s is None:
            self._standstill_since_s = now_s
        pending = self.pending
        if pending is None:
            return None, None
        since_s = self._standstill_since_s
        held_s = None if since_s is None else now_s - since_s
        refusal = switch_refusal(standstill_for_s=held_s, ato_engaged=ato_engaged)
        if refusal is None:
            self.pending, self._deferred_for = None, None
            self.switches += 1
            return pending, None
        # Reported once per version and kind of refusal, not at every tick of a long run.
        deferral = (pending.version, refusal.partition(" ")[0])
        if self._deferred_for == deferral:
            return None, None
        self._deferred_for = deferral
        text = f"switch to {pending.version} waits: {refusal}"
        return None, StackEvent(_WARNING, "track_data.switch_deferred", text)


def fetch_line(
    session: zenoh.Session,
    *,
    vehicle_id: str,
    line_id: str,
    store: TrackDataStore | None,
    stop: threading.Event,
    retry_s: float = FETCH_RETRY_S,
) -> Line:
    """The line to start on: the stored copy if the trackside holds no other version (or does
    not answer), else the trackside's, fetched, verified and stored. Without a usable copy it
    waits for a trackside to give the line, asking every ``retry_s`` [s] until ``stop``.

    Raises
    ------
    TrackDataUnavailableError
        ``stop`` was set before any trackside gave the line.
    """
    copy = _stored_copy(store, line_id)
    ask = m.LineDocumentRequest(vehicle_id=vehicle_id, line_id=line_id)
    while True:
        try:
            reply = request(session, LINE_DOCUMENT, ask, timeout_s=DOCUMENT_TIMEOUT_S, line=line_id)
        except ProtocolError as exc:
            _log.info("line %s: no answer from a trackside (%s)", line_id, exc)
            reply = None
        if copy is not None and (reply is None or reply.version in (None, copy.version())):
            return copy  # the copy is current, or nobody says otherwise
        if reply is not None and reply.version is not None and reply.document is not None:
            try:
                return _accept(reply.document, reply.version, line_id, store)
            except TrackDataCorruptError as exc:
                _log.warning("line %s refused: %s", line_id, exc)
                if copy is not None:
                    return copy  # the running node asks again (track_data task)
        elif reply is not None:
            _log.warning("line %s: the trackside does not hold it", line_id)
        if stop.wait(retry_s):
            raise TrackDataUnavailableError(f"line {line_id}: no trackside gave it")


def _accept(document: str, version: str, line_id: str, store: TrackDataStore | None) -> Line:
    if store is None:
        return verified_line(document, line_id=line_id, version=version)
    line = store.save(document, line_id=line_id, version=version)
    _log.info("line %s %s received, stored in %s", line_id, version, store.path(line_id))
    return line


def _stored_copy(store: TrackDataStore | None, line_id: str) -> Line | None:
    """The stored copy of the line, if there is a good one (a corrupt one is reported)."""
    if store is None:
        return None
    try:
        return store.load(line_id)
    except TrackDataCorruptError as exc:
        _log.warning("stored copy not used: %s", exc)
        return None
