"""The audit log: every command sent to a vehicle and every hold change, with its outcome.

Entries are written in their own transaction (a refused or failed command is audited even
though its request answers with an error), or queued to the recorder by callers on Zenoh's
threads.
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

__all__ = ["AuditResult", "audit_entry", "command_action", "list_entries", "record"]


class AuditResult(StrEnum):
    ACCEPTED = "accepted"
    """The vehicle accepted the command (or the hold changed)."""
    REFUSED = "refused"
    """The vehicle, or the trackside, refused it, with the reason in the detail."""
    TIMEOUT = "timeout"
    """The vehicle did not answer in time."""
    FAILED = "failed"
    """It could not be sent, or the answer was not valid."""


def audit_entry(
    *,
    user: str,
    vehicle_id: str | None,
    action: str,
    request: dict[str, Any],
    result: AuditResult,
    detail: str | None = None,
) -> AuditEntry:
    return AuditEntry(
        at=datetime.now(UTC),
        username=user,
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
