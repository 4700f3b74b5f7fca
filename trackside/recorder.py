"""The trackside's record of what the vehicles said: events, 1 Hz telemetry, audit entries.

Zenoh calls the bridge on its own threads; those callbacks must never wait on the database. They
hand what is to be kept to :class:`Recorder.offer`, which only appends to a bounded queue (when
full, the item is dropped and counted); one background thread writes the queue to the database
in batches. Telemetry is downsampled before it is queued: one status per vehicle per second of
the vehicle's own simulated time.

A row is queued as its columns' values and written with one bulk INSERT per table and batch,
not as ORM objects, and the writer wakes at most every :data:`COLLECT_S`: with a thousand
vehicles the objects' bookkeeping, the flush's unit of work and a thread woken on every row
took a third of the service's interpreter (docs/trackside.md, "Benchmark").

Audit entries never take that path: losing telemetry under load is acceptable, losing an audit
entry is not. :class:`AuditWriter` keeps them in an unbounded queue of their own (appending never
blocks and never drops) written by its own thread; a failed write (a database outage) is retried
until it succeeds, in the order offered, and :meth:`AuditWriter.close` logs at ERROR, in full,
any entry still unwritten when the service stops.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, NamedTuple, cast

from sqlalchemy import Table, insert
from sqlalchemy.orm import Session, sessionmaker

from protocol import messages as m
from trackside.models import AuditEntry, Base, TelemetrySample, VehicleEvent
from trackside.services.audit_chain import append, chained

__all__ = [
    "AuditWriter",
    "AuditWriterStats",
    "Recorder",
    "RecorderStats",
    "event_row",
    "insert_rows",
    "telemetry_row",
]

_log = logging.getLogger(__name__)

BATCH = 256
"""At most this many audit entries per transaction."""
ROW_BATCH = 2048
"""At most this many events and telemetry samples per transaction."""
ROWS_PER_STATEMENT = 500
"""Rows in one INSERT of :func:`insert_rows` (14 columns: 7 000 parameters, within SQLite's
32 766 and PostgreSQL's 65 535)."""
_PLACEHOLDERS = {"qmark": "?", "format": "%s", "pyformat": "%s"}
"""A positional parameter's mark in the drivers' paramstyles that :func:`insert_rows` writes."""
COLLECT_S = 0.05
"""Once woken, the recorder's writer waits this long for more rows before writing [s]."""


class Record(NamedTuple):
    """A row for the bounded queue: its table's model and its columns' values (audit entries
    go to :class:`AuditWriter`)."""

    model: type[VehicleEvent] | type[TelemetrySample]
    values: dict[str, Any]


@dataclass
class RecorderStats:
    queued: int = 0
    written: int = 0
    dropped: int = 0
    failed_batches: int = 0


def event_row(event: m.Event, received_at: datetime) -> Record:
    values = {
        "vehicle_id": event.vehicle_id,
        "seq": event.seq,
        "sim_time_s": event.sim_time_s,
        "received_at": received_at,
        "severity": event.severity.value,
        "code": event.code,
        "text": event.text,
    }
    return Record(VehicleEvent, values)


def telemetry_row(report: m.StatusReport, received_at: datetime) -> Record:
    vital = report.vital_control
    values = {
        "vehicle_id": report.vehicle_id,
        "sim_time_s": report.sim_time_s,
        "received_at": received_at,
        "position_m": report.position_m,
        "speed_mps": report.speed_mps,
        "traction_force_n": report.traction_force_n,
        "reference_speed_mps": report.reference_speed_mps,
        "permitted_speed_mps": report.permitted_speed_mps,
        "intervention_speed_mps": report.intervention_speed_mps,
        "ato_state": report.ato_state.value,
        "etcs_mode": report.etcs_mode.value,
        "sc_state": report.sc_state.value,
        "eb": bool(vital is not None and vital.eb_commanded),
        "journey_id": report.journey_id,
    }
    return Record(TelemetrySample, values)


def insert_rows(db: Session, model: type[Base], rows: list[dict[str, Any]]) -> None:
    """Insert ``rows`` (each the same columns' values) into ``model``'s table, in
    ``db``'s transaction, :data:`ROWS_PER_STATEMENT` rows a statement of many VALUES.

    Not the driver's ``executemany``: SQLite's driver executes a statement a row and gives the
    interpreter up and takes it back around each, and under load each taking waited for the
    other threads, 0.5 ms or more, while the transaction held the database's one writer lock:
    a hundred rows held it 165 ms at the median with three busy threads, where one statement of
    a hundred rows holds it 5 ms (docs/trackside.md, "Fifth sitting"). The statement is written
    here because SQLAlchemy compiles a statement of many VALUES again for each batch, which
    cost more than the rows. The values go through each column type's own conversion, as
    SQLAlchemy's would; a driver of another paramstyle is given ``executemany``."""
    if not rows:
        return
    dialect = db.get_bind().dialect
    mark = _PLACEHOLDERS.get(dialect.paramstyle)
    if mark is None:
        db.execute(insert(model), rows)
        return
    table = cast(Table, model.__table__)
    names = list(rows[0])
    if any(row.keys() != rows[0].keys() for row in rows):
        raise ValueError(f"rows for {table.name} with different columns")
    quote = dialect.identifier_preparer.quote
    columns = [table.c[name] for name in names]
    convert = [column.type.bind_processor(dialect) for column in columns]
    head = f"INSERT INTO {quote(table.name)} ({', '.join(quote(n) for n in names)}) VALUES "
    one = "(" + ", ".join([mark] * len(names)) + ")"
    connection = db.connection()
    for start in range(0, len(rows), ROWS_PER_STATEMENT):
        chunk = rows[start : start + ROWS_PER_STATEMENT]
        values = tuple(
            value if to_db is None or value is None else to_db(value)
            for row in chunk
            for value, to_db in zip((row[name] for name in names), convert, strict=True)
        )
        connection.exec_driver_sql(head + ", ".join([one] * len(chunk)), values)


@dataclass
class AuditWriterStats:
    queued: int = 0
    written: int = 0
    failed_writes: int = 0
    """Writes that failed and were retried (the entries stay queued)."""
    unwritten_at_close: int = 0


def _copy(entry: AuditEntry) -> AuditEntry:
    """A fresh entry of the same content: a retry must not reuse an object that a rolled-back
    session flushed (it may keep that attempt's id)."""
    return AuditEntry(
        at=entry.at,
        username=entry.username,
        vehicle_id=entry.vehicle_id,
        action=entry.action,
        request=entry.request,
        result=entry.result,
        detail=entry.detail,
    )


@dataclass
class AuditWriter:
    """Writes audit entries from its own thread, in the order offered; never drops one.

    :meth:`offer` appends to an unbounded queue and returns at once (for Zenoh's threads). A
    batch that fails to be written stays at the head of the queue and is retried every
    ``retry_s`` until it is written or the writer is closed.
    """

    factory: sessionmaker[Session]
    retry_s: float = 1.0
    stats: AuditWriterStats = field(default_factory=AuditWriterStats)

    def __post_init__(self) -> None:
        self._pending: deque[AuditEntry] = deque()
        self._changed = threading.Condition()
        self._writing = 0
        self._closing = False
        self._thread = threading.Thread(target=self._run, name="trackside-audit", daemon=True)
        self._thread.start()

    def offer(self, entry: AuditEntry) -> None:
        """Queue ``entry`` to be written (never blocks on the database, never drops)."""
        with self._changed:
            self._pending.append(_copy(entry))
            self.stats.queued += 1
            self._changed.notify_all()

    def flush(self, timeout_s: float = 5.0) -> bool:
        """Wait until every entry offered so far is written; False on timeout."""
        with self._changed:
            return self._changed.wait_for(
                lambda: not self._pending and not self._writing, timeout_s
            )

    def _next_batch(self) -> list[AuditEntry] | None:
        """The entries to write next (left queued until written); None once closed and empty."""
        with self._changed:
            self._changed.wait_for(lambda: self._pending or self._closing)
            if not self._pending:
                return None
            batch = [self._pending[index] for index in range(min(BATCH, len(self._pending)))]
            self._writing = len(batch)
            return batch

    def _run(self) -> None:
        while (batch := self._next_batch()) is not None:
            written = self._write(batch)
            with self._changed:
                if written:
                    for _ in batch:
                        self._pending.popleft()
                    self.stats.written += len(batch)
                self._writing = 0
                self._changed.notify_all()
                if not written and not self._closing:
                    self._changed.wait(self.retry_s)  # a close wakes it for a last attempt
            if not written and self._closing:
                return

    def _write(self, batch: list[AuditEntry]) -> bool:
        try:
            with chained(self.factory) as db:  # they join the hash chain in the order offered
                for entry in batch:
                    append(db, _copy(entry))
        except Exception:  # a database outage: keep the entries, retry
            self.stats.failed_writes += 1
            _log.exception("could not write %d audit entries; retrying", len(batch))
            return False
        return True

    def close(self, timeout_s: float = 10.0) -> None:
        """Write what is queued, then stop; an entry still unwritten is logged in full."""
        with self._changed:
            self._closing = True
            self._changed.notify_all()
        self._thread.join(timeout_s)
        with self._changed:
            left = list(self._pending)
        self.stats.unwritten_at_close = len(left)
        for entry in left:
            _log.error(
                "audit entry not written: at=%s user=%s vehicle=%s action=%s request=%s "
                "result=%s detail=%s",
                entry.at.isoformat(),
                entry.username,
                entry.vehicle_id,
                entry.action,
                entry.request,
                entry.result,
                entry.detail,
            )


@dataclass
class Recorder:
    """Writes what it is offered from one background thread; :meth:`offer` never blocks.

    Audit entries offered go to its :class:`AuditWriter` (``audit``), never to the bounded
    queue."""

    factory: sessionmaker[Session]
    capacity: int = 10_000
    telemetry_period_s: float = 1.0
    stats: RecorderStats = field(default_factory=RecorderStats)

    def __post_init__(self) -> None:
        self._pending: deque[Record] = deque()
        self._wake = threading.Event()
        self._idle = threading.Condition()
        self._writing = False
        self._closing = False
        self._last_sample: dict[str, int] = {}
        self._sample_lock = threading.Lock()
        self.audit = AuditWriter(self.factory)
        self._thread = threading.Thread(target=self._run, name="trackside-recorder", daemon=True)
        self._thread.start()

    def offer(self, row: Record | AuditEntry) -> bool:
        """Queue a row to be written; False (dropped and counted) when the queue is full. An
        audit entry is never dropped (:class:`AuditWriter`)."""
        if isinstance(row, AuditEntry):
            self.audit.offer(row)
            return True
        if len(self._pending) >= self.capacity:
            self.stats.dropped += 1
            return False
        self._pending.append(row)
        self.stats.queued += 1
        if not self._wake.is_set():  # the writer clears it before it takes rows
            self._wake.set()
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
            rows = self._idle.wait_for(lambda: not self._pending and not self._writing, timeout_s)
        return rows and self.audit.flush(timeout_s)

    def _run(self) -> None:
        while not (self._closing and not self._pending):
            self._wake.wait()
            self._wake.clear()
            if not self._closing:
                time.sleep(COLLECT_S)  # more rows come in the meantime: fewer, larger writes
            while self._pending:
                with self._idle:
                    batch = [
                        self._pending.popleft() for _ in range(min(ROW_BATCH, len(self._pending)))
                    ]
                    self._writing = True
                self._write(batch)

    def _write(self, batch: list[Record]) -> None:
        tables: dict[type[VehicleEvent] | type[TelemetrySample], list[dict[str, Any]]] = {}
        for model, values in batch:
            tables.setdefault(model, []).append(values)
        try:
            with self.factory() as db, db.begin():
                for model, rows in tables.items():
                    insert_rows(db, model, rows)
            self.stats.written += len(batch)
        except Exception:  # a database outage must not kill the recorder
            self.stats.failed_batches += 1
            _log.exception("could not record %d rows", len(batch))
        finally:
            with self._idle:
                self._writing = False
                self._idle.notify_all()

    def close(self, timeout_s: float = 10.0) -> None:
        """Write what is queued, then stop the threads."""
        self._closing = True
        self._wake.set()
        self._thread.join(timeout_s)
        self.audit.close(timeout_s)
