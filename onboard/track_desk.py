"""The node's track-data desk: asks the trackside, takes its answers, switches the parts.

Every ``track_data`` period the desk asks the trackside which version of the line it holds (the
Track Database Manager compares it); at every ``commands`` tick it takes what came back, asks
for the line when the versions differ (:class:`~onboard.track_transfer.TrackDataTransfer`
verifies and stores it), and switches to the pending track data once
:func:`~onboard.track_transfer.switch_refusal` allows it.

:func:`use_line` is the one place where the parts that read the line take new track data: the
Track Database Manager, ETCS, the ADF and its journey keeper, the sensor fusion. Each keeps its
state (same line id: the chainage keeps its meaning). The temporary speed restrictions the RBC
put in force are put in force again on the new data. The simulated vehicle (the plant, the
truth) keeps the world it was built with: track data on board describe the world, they do not
change it (docs/ato_ob.md, "Track data from the trackside").
"""

from __future__ import annotations

import threading
from pathlib import Path

from onboard.events import StackEvent
from onboard.ports import TracksidePorts
from onboard.runtime.clock import NS_PER_S
from onboard.session_link import Emit
from onboard.sfa.chain import SensorFusionChain
from onboard.stack import OnboardStack
from onboard.track_store import TrackDataStore
from onboard.track_transfer import STANDSTILL_MPS, TrackDataTransfer
from protocol import ProtocolError
from protocol import messages as m
from trackdb import TrackMap

__all__ = ["TrackDataDesk", "use_line"]

_INFO, _WARNING = m.EventSeverity.INFO, m.EventSeverity.WARNING


class TrackDataDesk:
    """Track data between the trackside and the onboard's parts, for one vehicle.

    Parameters
    ----------
    ports : TracksidePorts
        The vehicle's Zenoh seams.
    stack : OnboardStack
        The parts that read the line (with the Track Database Manager).
    sensor_fusion : SensorFusionChain
        The localisation, which reads the line too.
    track_dir : Path, optional
        Where verified copies are kept (None: not kept).
    emit : Emit
        Publishes an event at a tick [ns].
    """

    def __init__(
        self,
        ports: TracksidePorts,
        stack: OnboardStack,
        sensor_fusion: SensorFusionChain,
        track_dir: Path | None = None,
        *,
        emit: Emit,
    ) -> None:
        self.ports = ports
        self.stack = stack
        self.sensor_fusion = sensor_fusion
        self._emit = emit
        self._version: m.LineVersionReply | None = None
        self._lock = threading.Lock()
        store = None if track_dir is None else TrackDataStore(track_dir)
        self.transfer = TrackDataTransfer(stack.track_map.line.id, store)

    @property
    def pending_version(self) -> str | None:
        """The version received and verified, waiting for the switch (None: none)."""
        pending = self.transfer.pending
        return None if pending is None else pending.version

    def ask(self, now_ns: int) -> None:
        """The ``track_data`` task: ask the trackside's version of the line (answered
        asynchronously); an ask for the document lost since the last period is made again."""
        self.transfer.retry()
        try:
            self.ports.ask_line_version(self.stack.track_map.line.id, self.on_line_version)
        except ProtocolError as exc:
            self._emit(_WARNING, "track_data.query_failed", str(exc), now_ns)

    def on_line_version(self, reply: m.LineVersionReply) -> None:
        """The trackside's line version, on Zenoh's thread: taken at the next :meth:`step`."""
        with self._lock:
            self._version = reply

    def step(self, now_ns: int) -> None:
        """At the ``commands`` tick: the trackside's version and the documents received, the
        ask for the line if needed, the switch if due, each reported."""
        for event in [*self._take_version(), *self._take_documents(now_ns / NS_PER_S)]:
            self._emit(event.severity, event.code, event.text, now_ns)

    def _take_version(self) -> list[StackEvent]:
        """The Track Database Manager compares the trackside's version with its own."""
        with self._lock:
            reply, self._version = self._version, None
        if reply is None:
            return []
        database = self.stack.track_database
        matched_before = database.versions_match
        database.record_trackside_version(reply)
        if database.versions_match == matched_before and reply.version is not None:
            return []
        code = "track_data.match" if database.versions_match else "track_data.differ"
        severity = _INFO if database.versions_match else _WARNING
        text = f"trackside {reply.version or 'unknown'} onboard {database.onboard_version}"
        return [StackEvent(severity, code, text)]

    def _take_documents(self, now_s: float) -> list[StackEvent]:
        database = self.stack.track_database
        events = self.transfer.take(database.onboard_version)
        onboard, trackside = database.onboard_version, database.trackside_version
        dropped = self.transfer.forget_stale(trackside)
        if dropped is not None:
            events.append(dropped)
        wanted = self.transfer.wanted(onboard_version=onboard, trackside_version=trackside)
        if wanted is not None:
            try:
                self.ports.ask_line_document(database.line_id, self.transfer.on_reply)
            except ProtocolError as exc:
                events.append(StackEvent(_WARNING, "track_data.query_failed", str(exc)))
            else:
                self.transfer.asked(wanted)
        stack = self.stack
        standstill = abs(stack.speed_mps) < STANDSTILL_MPS and stack.etcs.standstill
        track_map, deferred = self.transfer.due(
            now_s, standstill=standstill, ato_engaged=stack.engaged
        )
        if deferred is not None:
            events.append(deferred)
        if track_map is not None:
            events += use_line(self.stack, self.sensor_fusion, track_map)
            text = f"{track_map.line.id} {onboard} → {track_map.version} at standstill"
            events.append(StackEvent(_INFO, "track_data.switched", text))
        return events


def use_line(
    stack: OnboardStack, sensor_fusion: SensorFusionChain, track_map: TrackMap
) -> list[StackEvent]:
    """Every onboard part that reads the line takes ``track_map`` (a version of the same line),
    keeping its state; the RBC's TSRs in force carried over. What to report."""
    previous = stack.track_map
    if track_map.line.id != previous.line.id:
        raise ValueError(f"track data of line {track_map.line.id}, not {previous.line.id}")
    events = _carry_speed_restrictions(previous, track_map)
    if stack.journey.plan is not None or stack.driving.journey is not None:
        events.append(
            StackEvent(_WARNING, "journey.dropped", "the journey was planned on the old track data")
        )
    stack.track_map = track_map
    stack.track_database.use_line(track_map)
    stack.etcs.use_line(track_map)
    stack.driving.use_line(track_map)
    stack.journey.use_line(track_map)
    sensor_fusion.use_line(track_map)
    return events


def _carry_speed_restrictions(previous: TrackMap, track_map: TrackMap) -> list[StackEvent]:
    """The TSRs the RBC put in force on the old track data, put in force on the new (those of
    the old document itself are not: the new document says which are in force)."""
    own = {tsr.id for tsr in previous.line.temporary_speed_restrictions}
    events = []
    for restriction in previous.temporary_speed_restrictions:
        if restriction.id in own:
            continue
        try:
            track_map.add_temporary_speed_restriction(restriction)
        except ValueError as exc:
            text = f"TSR {restriction.id} not on the new track data: {exc}"
            events.append(StackEvent(_WARNING, "etcs.tsr_dropped", text))
    return events
