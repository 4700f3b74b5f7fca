"""Database engine and schema migrations (Alembic, run programmatically at start-up)."""

from __future__ import annotations

import re
import sqlite3
import threading
from pathlib import Path

from alembic import command
from alembic.config import Config
from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import make_url

__all__ = ["create_database_engine", "migrate"]

MIGRATIONS_DIR = Path(__file__).resolve().parent / "migrations"

SQLITE_TIMEOUT_S = 5.0
"""How long a writer waits for another (this process's writer lock, then SQLite's)."""

_WRITE = re.compile(r"\s*(INSERT|UPDATE|DELETE|REPLACE|CREATE|DROP|ALTER)\b", re.IGNORECASE)
_writer_locks: dict[str, threading.Lock] = {}
_writer_locks_guard = threading.Lock()


def _writer_lock(database: str) -> threading.Lock:
    """The lock of this process's writers to one SQLite file (shared by its engines)."""
    key = str(Path(database).resolve())
    with _writer_locks_guard:
        return _writer_locks.setdefault(key, threading.Lock())


class _SqliteConnection(sqlite3.Connection):
    """A connection that takes its file's writer lock before its first write statement and
    gives it back when the transaction ends.

    SQLite has one writer at a time and a writer that finds the file locked sleeps in its busy
    handler, 1, 2, 5, 10, 15, 20, 25… ms between tries: with the recorder's bulk writes, the
    holds' renewals and the audit chain on several threads, a command's write waited tens of
    milliseconds for a lock free long before. This process's writers queue on a lock instead,
    and each is woken as soon as the one before it commits; a writer of another process still
    meets SQLite's busy handler."""

    writer: threading.Lock | None = None
    holding = False

    def take_writer(self) -> None:
        if self.writer is None or self.holding:
            return
        if not self.writer.acquire(timeout=SQLITE_TIMEOUT_S):
            raise sqlite3.OperationalError(
                f"database is locked: this process's other writer held it {SQLITE_TIMEOUT_S} s"
            )
        self.holding = True

    def _give_writer(self) -> None:
        if self.holding and self.writer is not None:
            self.holding = False
            self.writer.release()

    def commit(self) -> None:
        try:
            super().commit()
        finally:
            self._give_writer()

    def rollback(self) -> None:
        try:
            super().rollback()
        finally:
            self._give_writer()

    def close(self) -> None:
        try:
            super().close()
        finally:
            self._give_writer()


def create_database_engine(url: str) -> Engine:
    """An engine for a SQLite file or a PostgreSQL URL; SQLite enforces foreign keys and a file
    runs in WAL mode."""
    parsed = make_url(url)
    if parsed.drivername == "postgresql":
        parsed = parsed.set(drivername="postgresql+psycopg")
    if parsed.drivername.startswith("sqlite"):
        file_database = bool(parsed.database) and parsed.database != ":memory:"
        if file_database and parsed.database:
            Path(parsed.database).parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(
            parsed,
            connect_args={
                "check_same_thread": False,
                "factory": _SqliteConnection,
                "timeout": SQLITE_TIMEOUT_S,
            },
        )
        writer = _writer_lock(parsed.database) if file_database and parsed.database else None

        @event.listens_for(engine, "connect")
        def _foreign_keys(dbapi_connection, _record):  # type: ignore[no-untyped-def]
            if isinstance(dbapi_connection, _SqliteConnection):
                dbapi_connection.writer = writer
            cursor = dbapi_connection.cursor()
            cursor.execute("PRAGMA foreign_keys=ON")
            if file_database:
                # Readers never wait for the recorder's writes, and a commit costs no fsync (a
                # power cut may lose the last commits, never corrupt the file).
                cursor.execute("PRAGMA journal_mode=WAL")
                cursor.execute("PRAGMA synchronous=NORMAL")
            cursor.close()

        @event.listens_for(engine, "before_cursor_execute")
        def _take_writer(_conn, cursor, statement, *_args):  # type: ignore[no-untyped-def]
            connection = cursor.connection
            if isinstance(connection, _SqliteConnection) and _WRITE.match(statement):
                connection.take_writer()

        return engine
    return create_engine(parsed, pool_pre_ping=True)


def migrate(engine: Engine) -> None:
    """Bring the schema to the newest revision."""
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    with engine.begin() as connection:
        config.attributes["connection"] = connection
        command.upgrade(config, "head")
