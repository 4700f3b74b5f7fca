"""The audit log: every mutating call and every login, with its outcome (docs/security.md).

An entry names who (the user, or the username tried by a failed login), when, the action, its
request (JSON, never a password), the result and a detail. A command to a vehicle leaves two
entries that share ``request_id`` in their request: the intent (:attr:`AuditResult.REQUESTED`),
written before the vehicle is asked, and the outcome once it answered or could not be asked.

:func:`record` writes one entry, chained (``audit_chain``), in a transaction of its own, so a
refused or failed call is audited although its request fails. Callers on Zenoh's threads hand
their entries to the recorder's audit writer instead (``trackside.recorder.AuditWriter``), which
never drops one.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from enum import StrEnum
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from protocol import messages as m
from trackside.models import AuditEntry
from trackside.services.audit_chain import append, chained

__all__ = [
    "USERNAME_CHARS",
    "AuditResult",
    "audit_entry",
    "command_action",
    "list_entries",
    "record",
]


class AuditResult(StrEnum):
    REQUESTED = "requested"
    """The intent of a request to a vehicle, written before the vehicle is asked; its outcome
    follows in another entry with the same ``request_id``."""
    ACCEPTED = "accepted"
    """Done: the vehicle accepted the command, or the trackside made the change."""
    REFUSED = "refused"
    """The vehicle, or the trackside, refused it (a failed login too), with the reason in the
    detail."""
    TIMEOUT = "timeout"
    """The vehicle did not answer in time."""
    FAILED = "failed"
    """It could not be sent, the answer was not valid, or the trackside failed."""


USERNAME_CHARS = 64
"""The length of the user column; a longer username tried at login is cut to it."""


def audit_entry(
    *,
    user: str,
    vehicle_id: str | None,
    action: str,
    request: dict[str, Any],
    result: AuditResult,
    detail: str | None = None,
) -> AuditEntry:
    """An entry stamped now, its request as canonical JSON."""
    return AuditEntry(
        at=datetime.now(UTC),
        username=user[:USERNAME_CHARS],
        vehicle_id=vehicle_id,
        action=action,
        request=json.dumps(request, sort_keys=True),
        result=result.value,
        detail=detail,
    )


def record(factory: sessionmaker[Session], entry: AuditEntry) -> None:
    """Write one entry, chained (``audit_chain``), in a transaction of its own."""
    with chained(factory) as db:
        append(db, entry)


def list_entries(db: Session, *, vehicle_id: str | None, limit: int) -> list[AuditEntry]:
    """The newest ``limit`` entries (of one vehicle if given), oldest first."""
    query = select(AuditEntry)
    if vehicle_id is not None:
        query = query.where(AuditEntry.vehicle_id == vehicle_id)
    rows = list(db.scalars(query.order_by(AuditEntry.id.desc()).limit(limit)))
    rows.reverse()
    return rows


def command_action(body: m.CommandBody) -> str:
    """The audit action of a command: its type, with the request kind for confirmations."""
    if isinstance(body, m.OperatorConfirmCommand):
        return f"{body.type}.{body.request.value}"
    return body.type
