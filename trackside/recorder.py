"""The trackside's record of what the vehicles said: events, 1 Hz telemetry, audit entries.

Zenoh calls the bridge on its own threads; those callbacks must never wait on the database. They
hand what is to be kept to :class:`Recorder.offer`, which only appends to a bounded queue (when
full, the item is dropped and counted); one background thread writes the queue to the database
in batches. Telemetry is downsampled before it is queued: one status per vehicle per second of
the vehicle's own simulated time.
"""

from __future__ import annotations

import logging
import queue
import threading
from dataclasses import dataclass, field
from datetime import UTC, datetime

from sqlalchemy.orm import Session, sessionmaker

from protocol import messages as m
from trackside.models import AuditEntry, TelemetrySample, VehicleEvent
from trackside.services.audit_chain import append, chained

__all__ = ["Recorder", "RecorderStats", "event_row", "telemetry_row"]

_log = logging.getLogger(__name__)

BATCH = 256
"""At most this many rows per transaction."""

Record = VehicleEvent | TelemetrySample | AuditEntry


@dataclass
class RecorderStats:
    queued: int = 0
    written: int = 0
    dropped: int = 0
    failed_batches: int = 0


def event_row(event: m.Event, received_at: datetime) -> VehicleEvent:
    return VehicleEvent(
        vehicle_id=event.vehicle_id,
        seq=event.seq,
        sim_time_s=event.sim_time_s,
        received_at=received_at,
        severity=event.severity.value,
        code=event.code,
        text=event.text,
    )


def telemetry_row(report: m.StatusReport, received_at: datetime) -> TelemetrySample:
    vital = report.vital_control
    return TelemetrySample(
        vehicle_id=report.vehicle_id,
        sim_time_s=report.sim_time_s,
        received_at=received_at,
        position_m=report.position_m,
        speed_mps=report.speed_mps,
        traction_force_n=report.traction_force_n,
        reference_speed_mps=report.reference_speed_mps,
        permitted_speed_mps=report.permitted_speed_mps,
        intervention_speed_mps=report.intervention_speed_mps,
        ato_state=report.ato_state.value,
        etcs_mode=report.etcs_mode.value,
        sc_state=report.sc_state.value,
        eb=bool(vital is not None and vital.eb_commanded),
        journey_id=report.journey_id,
    )


@dataclass
class Recorder:
    """Writes what it is offered from one background thread; :meth:`offer` never blocks."""

    factory: sessionmaker[Session]
    capacity: int = 10_000
    telemetry_period_s: float = 1.0
    stats: RecorderStats = field(default_factory=RecorderStats)

    def __post_init__(self) -> None:
        self._queue: queue.Queue[Record | None] = queue.Queue(maxsize=self.capacity)
        self._last_sample: dict[str, int] = {}
        self._sample_lock = threading.Lock()
        self._idle = threading.Condition()
        self._busy = 0
        self._thread = threading.Thread(target=self._run, name="trackside-recorder", daemon=True)
        self._thread.start()

    def offer(self, row: Record) -> bool:
        """Queue a row to be written; False (dropped and counted) when the queue is full."""
        try:
            self._queue.put_nowait(row)
        except queue.Full:
            self.stats.dropped += 1
            return False
        with self._idle:
            self._busy += 1
        self.stats.queued += 1
        return True

    def offer_event(self, event: m.Event) -> bool:
        return self.offer(event_row(event, datetime.now(UTC)))

    def offer_status(self, report: m.StatusReport) -> bool:
        """Keep the first status of each period of the vehicle's simulated time. A clock that
        goes back (a restarted vehicle) starts a new series."""
        slot = int(report.sim_time_s // self.telemetry_period_s)
        with self._sample_lock:
            if self._last_sample.get(report.vehicle_id) == slot:
                return False
            self._last_sample[report.vehicle_id] = slot
        return self.offer(telemetry_row(report, datetime.now(UTC)))

    def flush(self, timeout_s: float = 5.0) -> bool:
        """Wait until everything offered so far is written (or dropped); for tests and shutdown."""
        with self._idle:
            return self._idle.wait_for(lambda: self._busy == 0, timeout_s)

    def _run(self) -> None:
        while True:
            first = self._queue.get()
            if first is None:
                return
            batch = [first]
            stop = False
            while len(batch) < BATCH:
                try:
                    row = self._queue.get_nowait()
                except queue.Empty:
                    break
                if row is None:
                    stop = True
                    break
                batch.append(row)
            self._write(batch)
            if stop:
                return

    def _write(self, batch: list[Record]) -> None:
        try:
            audit = [row for row in batch if isinstance(row, AuditEntry)]
            with self.factory() as db, db.begin():
                db.add_all([row for row in batch if not isinstance(row, AuditEntry)])
            if audit:  # they join the hash chain one by one, in the order offered
                with chained(self.factory) as db:
                    for row in audit:
                        append(db, row)
            self.stats.written += len(batch)
        except Exception:  # a database outage must not kill the recorder
            self.stats.failed_batches += 1
            _log.exception("could not record %d rows", len(batch))
        finally:
            with self._idle:
                self._busy -= len(batch)
                self._idle.notify_all()

    def close(self, timeout_s: float = 10.0) -> None:
        """Write what is queued, then stop the thread."""
        self._queue.put(None)
        self._thread.join(timeout_s)
