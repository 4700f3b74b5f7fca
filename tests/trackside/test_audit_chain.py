"""The audit log's hash chain (issue 20): ``ato audit verify`` finds a tampered row, on SQLite
and PostgreSQL."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from datetime import UTC, datetime

import pytest
from sqlalchemy import Engine, text
from sqlalchemy.orm import Session, sessionmaker
from typer.testing import CliRunner

from deploy.cli import app
from trackside.db import create_database_engine, migrate
from trackside.models import AuditEntry
from trackside.recorder import Recorder
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
