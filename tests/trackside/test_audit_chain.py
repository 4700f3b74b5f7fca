"""The audit log's hash chain (issue 20): ``ato audit verify`` finds a tampered row, on SQLite
and PostgreSQL."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from datetime import UTC, datetime
from typing import cast

import pytest
from sqlalchemy import Engine, select, text
from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session, sessionmaker
from typer.testing import CliRunner

from deploy.cli import app
from trackside.db import create_database_engine, migrate
from trackside.models import AuditEntry
from trackside.recorder import AuditWriter, Recorder
from trackside.services.audit import AuditResult, audit_entry, record


@pytest.fixture
def engine(database_url: str) -> Iterator[Engine]:
    engine = create_database_engine(database_url)
    migrate(engine)
    yield engine
    engine.dispose()


def _entry(index: int, user: str = "driver") -> AuditEntry:
    return audit_entry(
        user=user,
        vehicle_id="URV1",
        action="rd_target_speed",
        request={"target_speed_mps": float(index)},
        result=AuditResult.ACCEPTED,
    )


def _write(engine: Engine, count: int) -> None:
    factory = sessionmaker(engine, class_=Session, expire_on_commit=False)
    for index in range(count):
        record(factory, _entry(index))


def _verify(database_url: str) -> tuple[int, str]:
    result = CliRunner().invoke(app, ["audit", "verify", "--database", database_url])
    return result.exit_code, result.output


def test_an_untouched_log_verifies(engine: Engine, database_url: str) -> None:
    _write(engine, 5)
    code, output = _verify(database_url)
    assert code == 0, output
    assert "5 entries chained" in output


def test_a_changed_entry_is_found(engine: Engine, database_url: str) -> None:
    _write(engine, 5)
    with engine.begin() as connection:
        connection.execute(text("UPDATE audit_log SET result = 'refused' WHERE id = 3"))
    code, output = _verify(database_url)
    assert code == 1
    assert "entry 3: its content does not match its hash" in output


def test_a_removed_entry_is_found_in_the_middle_and_at_the_end(
    engine: Engine, database_url: str
) -> None:
    _write(engine, 5)
    with engine.begin() as connection:
        connection.execute(text("DELETE FROM audit_log WHERE id = 2"))
    code, output = _verify(database_url)
    assert code == 1
    assert "entry 3: its previous hash is not entry 1's hash" in output
    with engine.begin() as connection:
        connection.execute(text("DELETE FROM audit_log WHERE id IN (3, 4, 5)"))
    code, output = _verify(database_url)
    assert code == 1
    assert "the chain's head names entry 5, the log ends at entry 1" in output


def test_writers_on_several_threads_and_the_recorder_keep_one_chain(
    engine: Engine, database_url: str
) -> None:
    factory = sessionmaker(engine, class_=Session, expire_on_commit=False)
    recorder = Recorder(factory)
    threads = [threading.Thread(target=_write, args=(engine, 10)) for _ in range(3)]
    for thread in threads:
        thread.start()
    for index in range(10):
        recorder.offer(_entry(index, user="simulated-operator"))
    for thread in threads:
        thread.join()
    assert recorder.flush()
    recorder.close()
    code, output = _verify(database_url)
    assert code == 0, output
    assert "40 entries chained" in output


def test_the_entries_of_an_older_log_are_chained_by_the_migration(database_url: str) -> None:
    from alembic import command
    from alembic.config import Config

    from trackside.db import MIGRATIONS_DIR

    engine = create_database_engine(database_url)
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    with engine.begin() as connection:
        config.attributes["connection"] = connection
        command.upgrade(config, "0004")
        for index in range(3):
            connection.execute(
                text(
                    "INSERT INTO audit_log (at, username, vehicle_id, action, request, result)"
                    " VALUES (:at, 'admin', 'URV1', 'engage', :request, 'accepted')"
                ),
                {
                    "at": datetime(2026, 11, 1, 12, index, tzinfo=UTC),
                    "request": f'{{"n": {index}}}',
                },
            )
    migrate(engine)
    _write(engine, 1)  # and the chain goes on from them
    engine.dispose()
    code, output = _verify(database_url)
    assert code == 0, output
    assert "4 entries chained" in output


def test_the_recorder_never_drops_an_audit_entry_when_its_queue_is_full(
    engine: Engine, database_url: str
) -> None:
    factory = sessionmaker(engine, class_=Session, expire_on_commit=False)
    recorder = Recorder(factory, capacity=1)
    for index in range(50):
        assert recorder.offer(_entry(index, user="simulated-operator"))
    assert recorder.flush(10.0)
    recorder.close()
    assert recorder.stats.dropped == 0
    assert recorder.audit.stats.written == 50
    code, output = _verify(database_url)
    assert code == 0, output
    assert "50 entries chained" in output


class _Outage:
    """The database unreachable for the first ``failures`` transactions, then back."""

    def __init__(self, factory: sessionmaker[Session], failures: int) -> None:
        self._factory = factory
        self.failures = failures

    def __call__(self) -> Session:
        if self.failures > 0:
            self.failures -= 1
            raise OperationalError("connect", {}, ConnectionError("database unreachable"))
        return self._factory()


def test_the_audit_writer_retries_through_an_outage_in_order(
    engine: Engine, database_url: str
) -> None:
    outage = _Outage(sessionmaker(engine, class_=Session, expire_on_commit=False), failures=3)
    writer = AuditWriter(cast("sessionmaker[Session]", outage), retry_s=0.01)
    for index in range(5):
        writer.offer(_entry(index))
    assert writer.flush(10.0)
    writer.close()
    assert writer.stats.failed_writes == 3
    assert (writer.stats.written, writer.stats.unwritten_at_close) == (5, 0)
    with Session(engine) as db:
        speeds = [json.loads(e.request)["target_speed_mps"] for e in db.scalars(select(AuditEntry))]
    assert speeds == [0.0, 1.0, 2.0, 3.0, 4.0]
    code, output = _verify(database_url)
    assert code == 0, output


def test_an_entry_still_unwritten_when_the_writer_stops_is_logged_in_full(
    engine: Engine, caplog: pytest.LogCaptureFixture
) -> None:
    outage = _Outage(sessionmaker(engine, class_=Session, expire_on_commit=False), failures=10**6)
    writer = AuditWriter(cast("sessionmaker[Session]", outage), retry_s=0.01)
    writer.offer(_entry(7))
    writer.close(timeout_s=2.0)
    assert writer.stats.unwritten_at_close == 1
    assert any(
        "audit entry not written" in r.message and '"target_speed_mps": 7.0' in r.message
        for r in caplog.records
    )
