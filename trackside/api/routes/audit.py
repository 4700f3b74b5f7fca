"""The audit log of commands and hold changes (admin only)."""

from __future__ import annotations

import json
from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, Query
from pydantic import BaseModel

from trackside.api.deps import AdminUser, SessionDep
from trackside.models import AuditEntry
from trackside.services import audit

router = APIRouter(prefix="/audit", tags=["audit"])


class AuditPublic(BaseModel):
    id: int
    at: datetime
    user: str
    vehicle_id: str | None
    action: str
    request: dict[str, Any]
    result: audit.AuditResult
    detail: str | None

    @classmethod
    def from_entry(cls, entry: AuditEntry) -> AuditPublic:
        return cls(
            id=entry.id,
            at=entry.at,
            user=entry.username,
            vehicle_id=entry.vehicle_id,
            action=entry.action,
            request=json.loads(entry.request),
            result=audit.AuditResult(entry.result),
            detail=entry.detail,
        )


@router.get("")
def read_audit(
    db: SessionDep,
    _admin: AdminUser,
    vehicle_id: Annotated[str | None, Query(max_length=32)] = None,
    limit: Annotated[int, Query(ge=1, le=10_000)] = 200,
) -> list[AuditPublic]:
    """The newest audit entries (of one vehicle if given), oldest first."""
    entries = audit.list_entries(db, vehicle_id=vehicle_id, limit=limit)
    return [AuditPublic.from_entry(entry) for entry in entries]
