"""The audit log of commands and hold changes (admin only)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from trackside.api.deps import AdminUser, SessionDep
from trackside.api.schemas import AuditPublic
from trackside.services import audit

__all__ = ["router"]

router = APIRouter(prefix="/audit", tags=["audit"])


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
