"""The audit entry of a mutating route: one per call that reaches the route, whatever its outcome.

A route wraps what it changes in :meth:`AuditTrail.action`. The entry is written once the
request's own transaction has ended (``deps.get_db`` depends on :func:`audit_trail`, so the
trail is closed after the session): ``accepted`` when the route returned and its changes were
committed, otherwise the result that the error is answered with (``refused`` for a 4xx,
``timeout`` for a 504, ``failed`` for anything else, a commit that failed included) and the
error's message as the detail. Written after the transaction, the entry reports what happened,
and its own write never waits on the request's write lock (SQLite has one writer at a time).

The entry is written, chained, in a transaction of its own (``services.audit.record``); should
that fail after the change was committed, the entry goes to the recorder's audit writer, which
keeps it and retries until it is written (``trackside.recorder.AuditWriter``): never dropped.

Calls stopped before the route runs (no or a bad token: 401, a role too low: 403, a body that
does not validate: 422) change nothing and are not audited; every login is, by its route.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import anyio
import anyio.to_thread
from fastapi import HTTPException, Request, status
from sqlalchemy.orm import Session, sessionmaker

from trackside.api.exception_handlers import ERROR_ANSWERS
from trackside.models import AuditEntry
from trackside.recorder import AuditWriter
from trackside.services import audit

__all__ = ["AuditNote", "AuditTrail", "audit_trail", "result_of"]

_log = logging.getLogger(__name__)


@dataclass
class AuditNote:
    """One call to audit: who, what, and what the route adds to its request while it runs."""

    user: str
    action: str
    vehicle_id: str | None
    request: dict[str, Any] = field(default_factory=dict)
    detail: str | None = None
    """The detail of a call that succeeded (a failed one's is its error's message)."""


def _status_of(exc: BaseException) -> int:
    if isinstance(exc, HTTPException):
        return exc.status_code
    for error in type(exc).__mro__:
        answer = ERROR_ANSWERS.get(error)
        if answer is not None:
            return answer.status_code
    return status.HTTP_500_INTERNAL_SERVER_ERROR


def result_of(exc: BaseException) -> audit.AuditResult:
    """The audit result of a call that raised ``exc``, from the status it is answered with."""
    code = _status_of(exc)
    if code == status.HTTP_504_GATEWAY_TIMEOUT:
        return audit.AuditResult.TIMEOUT
    if code < status.HTTP_500_INTERNAL_SERVER_ERROR:
        return audit.AuditResult.REFUSED
    return audit.AuditResult.FAILED


def _detail(exc: BaseException) -> str:
    if isinstance(exc, HTTPException):
        return str(exc.detail)
    return str(exc) or type(exc).__name__


@dataclass
class AuditTrail:
    """The audit entries of one request, written by :meth:`close` when the request ends."""

    factory: sessionmaker[Session]
    fallback: AuditWriter | None = None
    """Where an entry goes when it cannot be written at once."""
    notes: list[AuditNote] = field(default_factory=list)

    @contextmanager
    def action(
        self,
        user: str,
        action: str,
        *,
        vehicle_id: str | None = None,
        request: dict[str, Any] | None = None,
    ) -> Iterator[AuditNote]:
        """Audit the block as one call of ``action`` by ``user`` (one entry, whatever becomes
        of the request); the block may add to the note's request and set its detail."""
        note = AuditNote(user, action, vehicle_id, dict(request or {}))
        self.notes.append(note)
        yield note

    def close(self, error: BaseException | None) -> None:
        """Write the entry of each call, with the request's outcome: ``error`` if it failed."""
        for note in self.notes:
            result = audit.AuditResult.ACCEPTED if error is None else result_of(error)
            detail = note.detail if error is None else _detail(error)
            self._write(
                audit.audit_entry(
                    user=note.user,
                    vehicle_id=note.vehicle_id,
                    action=note.action,
                    request=note.request,
                    result=result,
                    detail=detail,
                )
            )
        self.notes.clear()

    def _write(self, entry: AuditEntry) -> None:
        try:
            audit.record(self.factory, entry)
        except Exception:
            if self.fallback is None:
                raise
            _log.exception("audit entry %s queued to be retried", entry.action)
            self.fallback.offer(entry)


async def audit_trail(request: Request) -> AsyncIterator[AuditTrail]:
    """The request's audit trail (a dependency of ``get_db``, so closed after its session),
    closed with the request's outcome.

    Made on the event loop (it does no I/O): a request that audits nothing costs no trip to the
    thread pool; one that does writes its entries there, shielded from the request's
    cancellation so that an entry is never lost to a client that went away."""
    recorder = getattr(request.app.state, "recorder", None)
    trail = AuditTrail(
        request.app.state.session_factory, None if recorder is None else recorder.audit
    )
    try:
        yield trail
    except BaseException as exc:
        await _close(trail, exc)
        raise
    await _close(trail, None)


async def _close(trail: AuditTrail, error: BaseException | None) -> None:
    if trail.notes:
        with anyio.CancelScope(shield=True):
            await anyio.to_thread.run_sync(trail.close, error)
