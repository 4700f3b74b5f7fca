"""The audit log's hash chain: appending an entry, and verifying the whole log.

Each entry carries ``prev_hash`` (the previous entry's hash; :data:`GENESIS` for the first) and
``hash``, the SHA-256 of its canonical content (id, time, user, vehicle, action, request, result,
detail) and ``prev_hash``. The head row (``audit_chain_head``, id 1) holds the last entry's id
and hash. An append locks the head (``SELECT ... FOR UPDATE`` on PostgreSQL, where several
trackside instances may share the log; SQLite serialises writers, and a process-wide lock
serialises this process's threads), so the chain is a line even under concurrent writers.

:func:`verify` recomputes every hash in id order: a changed entry fails its own hash, a removed
or inserted one breaks the link to its neighbour, a removed last entry no longer matches the
head. The chain shows tampering by anyone without the means to rewrite every later entry and
the head consistently; an off-site copy of the head's hash (the log's "anchor") makes even
that visible.
"""

from __future__ import annotations

import hashlib
import json
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from trackside.models import AuditChainHead, AuditEntry

__all__ = ["GENESIS", "ChainReport", "append", "chained", "entry_hash", "verify"]

GENESIS = "0" * 64
"""The previous hash of the first entry."""
HEAD_ID = 1

_append_lock = threading.Lock()


def _utc_text(at: datetime) -> str:
    """A time as UTC text, the same whether the database gave it back aware or naive (SQLite)."""
    aware = at.replace(tzinfo=UTC) if at.tzinfo is None else at.astimezone(UTC)
    return aware.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def entry_hash(row: Any, prev_hash: str) -> str:
    """SHA-256 (hex) of an entry's canonical content and ``prev_hash``; ``row`` an
    :class:`AuditEntry` or a mapping of its columns (a migration's rows)."""

    def get(name: str) -> Any:
        return getattr(row, name) if isinstance(row, AuditEntry) else row[name]

    content = [
        get("id"),
        _utc_text(get("at")),
        get("username"),
        get("vehicle_id"),
        get("action"),
        get("request"),
        get("result"),
        get("detail"),
        prev_hash,
    ]
    canonical = json.dumps(content, ensure_ascii=False, separators=(",", ":"))
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


@contextmanager
def chained(factory: sessionmaker[Session]) -> Iterator[Session]:
    """A transaction to :func:`append` in, committed at the end: this process's appenders one
    at a time for the whole transaction (SQLite's writers would otherwise read a head another
    has moved on; PostgreSQL's row lock on the head then orders the processes)."""
    with _append_lock, factory() as db, db.begin():
        yield db


def append(db: Session, entry: AuditEntry) -> AuditEntry:
    """Add ``entry`` to the chain in ``db``'s transaction, one opened by :func:`chained`."""
    head = db.scalars(
        select(AuditChainHead).where(AuditChainHead.id == HEAD_ID).with_for_update()
    ).one_or_none()
    if head is None:
        head = AuditChainHead(id=HEAD_ID, last_id=None, last_hash=GENESIS)
        db.add(head)
    db.add(entry)
    db.flush()  # the entry's id is part of its hash
    entry.prev_hash = head.last_hash
    entry.hash = entry_hash(entry, head.last_hash)
    head.last_id, head.last_hash = entry.id, entry.hash
    db.flush()
    return entry


@dataclass(frozen=True)
class ChainReport:
    """What :func:`verify` found: the entries checked and each break of the chain."""

    entries: int
    problems: tuple[str, ...]

    @property
    def intact(self) -> bool:
        return not self.problems


def verify(db: Session) -> ChainReport:
    """Recompute the chain over every entry, in id order, and compare it with the head."""
    problems: list[str] = []
    previous, last_id, count = GENESIS, None, 0
    for entry in db.scalars(select(AuditEntry).order_by(AuditEntry.id)):
        count += 1
        if entry.prev_hash != previous:
            problems.append(
                f"entry {entry.id}: its previous hash is not entry {last_id}'s hash "
                "(an entry removed or inserted before it)"
                if last_id is not None
                else f"entry {entry.id}: the first entry does not start the chain"
            )
        if entry.hash != entry_hash(entry, entry.prev_hash or ""):
            problems.append(f"entry {entry.id}: its content does not match its hash (changed)")
        previous, last_id = entry.hash or "", entry.id
    head = db.get(AuditChainHead, HEAD_ID)
    head_id, head_hash = (None, GENESIS) if head is None else (head.last_id, head.last_hash)
    if (head_id, head_hash) != (last_id, previous):
        problems.append(
            f"the chain's head names entry {head_id}, the log ends at entry {last_id} "
            "(entries removed from the end, or the head changed)"
        )
    return ChainReport(entries=count, problems=tuple(problems))
