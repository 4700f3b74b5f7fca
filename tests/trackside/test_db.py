"""A SQLite file's writers in one process queue on its writer lock, not in SQLite's busy
handler (trackside.db)."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
from sqlalchemy import Engine, exc, text

from trackside import db as database


@pytest.fixture
def engine(tmp_path: Path) -> Engine:
    engine = database.create_database_engine(f"sqlite:///{tmp_path / 'writers.db'}")
    with engine.begin() as connection:
        connection.execute(text("CREATE TABLE t (x INTEGER)"))
    return engine


def _lock(engine: Engine) -> threading.Lock:
    assert engine.url.database is not None
    return database._writer_lock(engine.url.database)


def test_a_second_writer_waits_for_the_first_to_commit_then_writes(engine: Engine) -> None:
    written = threading.Event()
    order: list[str] = []

    def second_writer() -> None:
        with engine.begin() as connection:
            connection.execute(text("INSERT INTO t VALUES (2)"))
            order.append("second wrote")
        written.set()

    with engine.begin() as first:
        first.execute(text("INSERT INTO t VALUES (1)"))
        assert _lock(engine).locked()
        thread = threading.Thread(target=second_writer)
        thread.start()
        assert not written.wait(0.3)  # it waits for this transaction
        with engine.connect() as reader:  # a reader does not wait
            assert reader.execute(text("SELECT count(*) FROM t")).scalar_one() == 0
        order.append("first committing")
    assert written.wait(5.0)
    thread.join()
    assert order == ["first committing", "second wrote"]
    assert not _lock(engine).locked()
    with engine.connect() as reader:
        assert sorted(reader.execute(text("SELECT x FROM t")).scalars()) == [1, 2]


def test_the_lock_is_given_back_by_a_rollback_and_a_close(engine: Engine) -> None:
    with engine.connect() as connection:
        transaction = connection.begin()
        connection.execute(text("INSERT INTO t VALUES (1)"))
        assert _lock(engine).locked()
        transaction.rollback()
        assert not _lock(engine).locked()
        connection.execute(text("INSERT INTO t VALUES (2)"))
        assert _lock(engine).locked()
    assert not _lock(engine).locked()  # returned to the pool: rolled back
    raw = engine.raw_connection()
    raw.cursor().execute("INSERT INTO t VALUES (3)")
    raw.dbapi_connection.take_writer()  # type: ignore[union-attr]
    raw.invalidate()  # closed without a commit
    assert not _lock(engine).locked()
    with engine.connect() as reader:
        assert reader.execute(text("SELECT count(*) FROM t")).scalar_one() == 0


def test_a_writer_held_too_long_is_an_error_and_nothing_is_written(
    engine: Engine, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(database, "SQLITE_TIMEOUT_S", 0.2)
    errors: list[Exception] = []

    def second_writer() -> None:
        try:
            with engine.begin() as connection:
                connection.execute(text("INSERT INTO t VALUES (2)"))
        except exc.OperationalError as error:
            errors.append(error)

    with engine.begin() as first:
        first.execute(text("INSERT INTO t VALUES (1)"))
        thread = threading.Thread(target=second_writer)
        thread.start()
        thread.join(5.0)
    assert len(errors) == 1
    assert "database is locked" in str(errors[0])
    assert not _lock(engine).locked()
    with engine.connect() as reader:
        assert list(reader.execute(text("SELECT x FROM t")).scalars()) == [1]
