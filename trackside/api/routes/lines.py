"""Lines: the track database, its versions, import (audited) and export, and profiles for
plotting."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Depends, Query, Request, Response, status

from trackdb import Line
from trackside.api.deps import AdminUser, AuditDep, ObserverUser, SessionDep
from trackside.api.schemas import (
    LineProfilePublic,
    LinePublic,
    LineRejectedPublic,
    LineVersionPublic,
    LineVersionRef,
)
from trackside.services import lines

__all__ = ["router"]

router = APIRouter(prefix="/lines", tags=["lines"])

VersionQuery = Annotated[
    str | None, Query(description="A stored version (SHA-256); the current one by default")
]
NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"description": "No such line or version"}}
REJECTED: dict[int | str, dict[str, Any]] = {
    422: {"model": LineRejectedPublic, "description": "Refused, with every problem found"}
}
LINE_DOCUMENT_BODY = {
    "requestBody": {
        "required": True,
        "description": "A line document (trackdb/line.schema.json)",
        # The Line schema is in the components because read_line answers with it.
        "content": {"application/json": {"schema": {"$ref": "#/components/schemas/Line"}}},
    }
}


async def _raw_body(request: Request) -> bytes:
    return await request.body()


RawBody = Annotated[bytes, Depends(_raw_body)]


def _json_document(document: str, version: str, *, download: str | None = None) -> Response:
    headers = {"ETag": f'"{version}"'}
    if download is not None:
        headers["Content-Disposition"] = f'attachment; filename="{download}"'
    return Response(content=document, media_type="application/json", headers=headers)


@router.get("")
def list_lines(db: SessionDep, _user: ObserverUser) -> list[LinePublic]:
    """List the stored lines, each at its current version."""
    return [LinePublic.from_summary(summary) for summary in lines.list_lines(db)]


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    responses={
        200: {"model": LinePublic, "description": "That version was stored already"},
        409: {"description": "A concurrent import of the same line won"},
        **REJECTED,
    },
    openapi_extra=LINE_DOCUMENT_BODY,
)
def import_line(
    body: RawBody, response: Response, db: SessionDep, admin: AdminUser, trail: AuditDep
) -> LinePublic:
    """Import a line document (admin only); it becomes the line's current version."""
    # The audit entry names the line and version stored, not the whole document.
    with trail.action(admin.username, "line.import", request={"bytes": len(body)}) as note:
        outcome = lines.import_line(db, body)
        summary = outcome.summary
        note.request |= {"line_id": summary.id, "version": summary.version}
        note.detail = None if outcome.new_version else "that version was stored already"
    if not outcome.new_version:
        response.status_code = status.HTTP_200_OK
    return LinePublic.from_summary(summary)


@router.get("/{line_id}", response_model=Line, responses=NOT_FOUND)
def read_line(
    line_id: str, db: SessionDep, _user: ObserverUser, version: VersionQuery = None
) -> Response:
    """The full line document, at its current version or at ``version``."""
    document, version = lines.line_document(db, line_id, version)
    return _json_document(document, version)


@router.get(
    "/{line_id}/export",
    responses={200: {"content": {"application/json": {}}}, **NOT_FOUND},
    response_class=Response,
)
def export_line(
    line_id: str, db: SessionDep, _user: ObserverUser, version: VersionQuery = None
) -> Response:
    """Download the line's canonical JSON; its SHA-256 is the version."""
    document, version = lines.line_document(db, line_id, version)
    return _json_document(document, version, download=f"{line_id}-{version[:12]}.json")


@router.get("/{line_id}/version", responses=NOT_FOUND)
def read_version(line_id: str, db: SessionDep, _user: ObserverUser) -> LineVersionRef:
    """The line's current version, for comparing track data with the onboard."""
    return LineVersionRef(id=line_id, version=lines.current_version(db, line_id))


@router.get("/{line_id}/versions", responses=NOT_FOUND)
def list_versions(line_id: str, db: SessionDep, _user: ObserverUser) -> list[LineVersionPublic]:
    """Every stored version of the line, oldest first."""
    return [LineVersionPublic.from_summary(s) for s in lines.line_versions(db, line_id)]


@router.get("/{line_id}/profile", responses={**NOT_FOUND, **REJECTED})
def read_profile(
    line_id: str,
    db: SessionDep,
    _user: ObserverUser,
    from_m: Annotated[float | None, Query(alias="from", description="First chainage [m]")] = None,
    to_m: Annotated[
        float | None, Query(alias="to", description="Last chainage [m]; past the length on a ring")
    ] = None,
    step_m: Annotated[
        float | None, Query(alias="step", description="Sample step [m]; at most 20001 samples")
    ] = None,
    version: VersionQuery = None,
) -> LineProfilePublic:
    """Gradient, curvature, line speed, MRSP and altitude sampled along the line, SI units."""
    profile = lines.line_profile(
        db, line_id, from_m=from_m, to_m=to_m, step_m=step_m, version=version
    )
    return LineProfilePublic.from_profile(profile)
