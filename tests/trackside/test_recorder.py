"""The recorder's telemetry and events: one status per vehicle and second kept, written in bulk
from its own thread on SQLite and PostgreSQL; a full queue drops and counts."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime

import pytest
from sqlalchemy import Engine, func, insert, select
from sqlalchemy.orm import Session, sessionmaker

from protocol import messages as m
from tests.trackside.reports import status_report
from trackside.db import create_database_engine, migrate
from trackside.models import TelemetrySample, VehicleEvent
from trackside.recorder import ROWS_PER_STATEMENT, Recorder, insert_rows, telemetry_row


@pytest.fixture
def factory(database_url: str) -> Iterator[sessionmaker[Session]]:
    engine: Engine = create_database_engine(database_url)
    migrate(engine)
    yield sessionmaker(engine, class_=Session, expire_on_commit=False)
    engine.dispose()


def _report(vehicle_id: str, sim_time_s: float) -> m.StatusReport:
    return status_report(vehicle_id, 100.0, line_id="bologna-ring").model_copy(
        update={"sim_time_s": sim_time_s}
    )


def test_one_status_a_second_per_vehicle_and_every_event_are_written(
    factory: sessionmaker[Session],
) -> None:
    recorder = Recorder(factory)
    kept = [
        recorder.offer_status(_report(vehicle, 0.2 * step))
        for step in range(25)  # 5 s at 5 Hz
        for vehicle in ("REC1", "REC2")
    ]
    event = m.Event(
        vehicle_id="REC1", seq=1, sim_time_s=1.0, severity=m.EventSeverity.INFO, code="x", text="y"
    )
    assert recorder.offer_event(event)
    assert recorder.flush()
    recorder.close()
    assert sum(kept) == 10
    with factory() as db:
        samples = db.scalars(
            select(TelemetrySample.sim_time_s)
            .where(TelemetrySample.vehicle_id == "REC1")
            .order_by(TelemetrySample.sim_time_s)
        ).all()
        events = db.scalar(select(func.count()).where(VehicleEvent.vehicle_id == "REC1"))
    assert samples == pytest.approx([0.0, 1.0, 2.0, 3.0, 4.0])
    assert events == 1
    assert recorder.stats.written == 11


def test_a_full_queue_drops_and_counts_and_the_rest_is_written(
    factory: sessionmaker[Session],
) -> None:
    recorder = Recorder(factory, capacity=3)
    offered = [recorder.offer_status(_report(f"REC{index}", 0.0)) for index in range(50)]
    assert recorder.flush()
    recorder.close()
    assert recorder.stats.dropped == offered.count(False)
    assert recorder.stats.written == offered.count(True) >= 3


def test_rows_written_in_one_statement_read_back_as_the_orm_writes_them(
    factory: sessionmaker[Session],
) -> None:
    """:func:`insert_rows` writes each column's value through its type's conversion (an aware
    time, a flag, a missing value), whatever the order of a row's keys, in statements of at
    most ``ROWS_PER_STATEMENT`` rows; SQLAlchemy's own insert of the same rows reads back the
    same."""
    at = datetime(2026, 12, 7, 14, 0, 0, 123456, tzinfo=UTC)
    count = ROWS_PER_STATEMENT + 3
    rows = [telemetry_row(_report("SIMA", float(i)), at).values for i in range(count)]
    rows[1] = dict(reversed(list(rows[1].items())))  # the same columns, in another order
    rows[2]["reference_speed_mps"] = None
    rows[3]["eb"] = True
    mirror = [row | {"vehicle_id": "SIMB"} for row in rows]
    with factory() as db, db.begin():
        insert_rows(db, TelemetrySample, rows)
        db.execute(insert(TelemetrySample), mirror)

    def read(vehicle_id: str) -> list[tuple[object, ...]]:
        with factory() as db:
            samples = db.scalars(
                select(TelemetrySample)
                .where(TelemetrySample.vehicle_id == vehicle_id)
                .order_by(TelemetrySample.sim_time_s)
            )
            return [
                (s.sim_time_s, s.received_at.replace(tzinfo=None), s.eb, s.reference_speed_mps)
                + (s.position_m, s.ato_state, s.journey_id)
                for s in samples
            ]

    ours = read("SIMA")
    assert len(ours) == count
    assert ours == read("SIMB")
    assert ours[0][1] == at.replace(tzinfo=None)
    assert ours[3][2] is True
    assert ours[2][3] is None


def test_rows_of_different_columns_are_refused_and_nothing_is_written(
    factory: sessionmaker[Session],
) -> None:
    at = datetime(2026, 12, 7, tzinfo=UTC)
    rows = [telemetry_row(_report("SIMC", float(i)), at).values for i in range(2)]
    del rows[1]["journey_id"]
    with pytest.raises(ValueError, match="different columns"), factory() as db, db.begin():
        insert_rows(db, TelemetrySample, rows)
    with factory() as db:
        assert db.scalar(select(func.count()).select_from(TelemetrySample)) == 0
