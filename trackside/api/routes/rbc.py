"""The RBC emulator: read, issue, extend, shorten and revoke a vehicle's movement authority (MA),
and read, put in force and revoke its temporary speed restrictions (TSRs).

Reading is for every role; changes are for admins and each leaves an audit entry (refused ones
too, with the reason). A refused change sends nothing and changes nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Any

from fastapi import APIRouter, Depends, HTTPException, Path, Request, status

from protocol import messages as m
from protocol.units import MPS_PER_KMH
from trackside.api.deps import AdminUser, AuditDep, ObserverUser
from trackside.api.schemas import MovementAuthorityPublic, RefusedPublic, SpeedRestrictionCreate
from trackside.errors import ConflictError
from trackside.models import User
from trackside.rbc import MovementAuthorityIssue, RbcEmulator
from trackside.rbc_rules import speed_restriction
from trackside.separation_supervisor import SeparationSupervisor

__all__ = ["router"]

router = APIRouter(prefix="/rbc", tags=["rbc"])

VehiclePath = Annotated[
    str, Path(pattern=r"^[A-Za-z0-9_-]{1,32}$", description="Vehicle id", examples=["URV1"])
]


def get_rbc(request: Request) -> RbcEmulator:
    rbc: RbcEmulator = request.app.state.rbc
    return rbc


RbcDep = Annotated[RbcEmulator, Depends(get_rbc)]


def get_separation(request: Request) -> SeparationSupervisor | None:
    """The RBC's separation of the trains, when the trackside runs one."""
    separation: SeparationSupervisor | None = getattr(request.app.state, "separation", None)
    return separation


SeparationDep = Annotated[SeparationSupervisor | None, Depends(get_separation)]


def _manual_change_refused(separation: SeparationSupervisor | None) -> None:
    if separation is not None:
        raise ConflictError(
            "the RBC separates the trains here: it extends and shortens the MAs itself; "
            "give the train a new route with POST /api/v1/rbc/{vehicle}/ma"
        )


NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {"description": "The RBC holds no MA for the vehicle"}
}
REFUSED: dict[int | str, dict[str, Any]] = {
    409: {"model": RefusedPublic, "description": "The EoA would lie at or behind the vehicle"},
    422: {
        "model": RefusedPublic,
        "description": "Refused: a bad body or an MA the RBC cannot send",
    },
    503: {"description": "The MA could not be published; nothing changed"},
}


def _public(rbc: RbcEmulator, message: m.MovementAuthorityMessage) -> MovementAuthorityPublic:
    authority = message.authority
    return MovementAuthorityPublic(
        movement_authority=message,
        supervised_location_m=None if authority is None else authority.supervised_location_m,
        acknowledgement=rbc.acknowledgement(message.vehicle_id),
    )


def _changed(
    trail: AuditDep,
    user: User,
    vehicle_id: str,
    action: str,
    request: dict[str, Any],
    change: Callable[[], m.MovementAuthorityMessage],
) -> m.MovementAuthorityMessage:
    """Make an MA change, audited with the MA's id and EoA once sent (or the refusal)."""
    with trail.action(user.username, action, vehicle_id=vehicle_id, request=request) as note:
        message = change()
        authority = message.authority
        note.request["ma_id"] = message.ma_id
        if authority is not None:
            note.request["end_of_authority_m"] = authority.end_of_authority_m
    return message


@router.get("/{vehicle_id}/ma", responses=NOT_FOUND)
def read_movement_authority(
    vehicle_id: VehiclePath, rbc: RbcDep, _user: ObserverUser
) -> MovementAuthorityPublic:
    """The vehicle's MA in force, as the RBC last sent it."""
    current = rbc.current(vehicle_id)
    if current is None:
        raise HTTPException(
            status_code=status.HTTP_404_NOT_FOUND,
            detail=f"the RBC holds no movement authority for {vehicle_id}",
        )
    return _public(rbc, current)


@router.post("/{vehicle_id}/ma", status_code=status.HTTP_201_CREATED, responses=REFUSED)
def issue_movement_authority(
    vehicle_id: VehiclePath,
    body: MovementAuthorityIssue,
    rbc: RbcDep,
    separation: SeparationDep,
    user: AdminUser,
    trail: AuditDep,
) -> MovementAuthorityPublic:
    """Issue a new MA to the vehicle (admin only), replacing any it holds. When the RBC
    separates the trains, the body is the train's route and the MA ends short of the train
    ahead (extended as it moves on)."""
    request = body.model_dump(mode="json")

    def issue() -> m.MovementAuthorityMessage:
        if separation is None:
            return rbc.issue(vehicle_id, body)
        return separation.request(vehicle_id, body)

    message = _changed(trail, user, vehicle_id, "rbc.ma_issue", request, issue)
    return _public(rbc, message)


@router.post("/{vehicle_id}/ma/extend", responses={**NOT_FOUND, **REFUSED})
def extend_movement_authority(
    vehicle_id: VehiclePath,
    body: m.MovementAuthorityEnd,
    rbc: RbcDep,
    separation: SeparationDep,
    user: AdminUser,
    trail: AuditDep,
) -> MovementAuthorityPublic:
    """Move the EoA forward, with the new end's danger point, overlap and release speed (409
    when the RBC separates the trains: it extends the MAs itself)."""
    request = body.model_dump(mode="json")

    def extend() -> m.MovementAuthorityMessage:
        _manual_change_refused(separation)
        return rbc.extend(vehicle_id, body)

    message = _changed(trail, user, vehicle_id, "rbc.ma_extend", request, extend)
    return _public(rbc, message)


@router.post("/{vehicle_id}/ma/shorten", responses={**NOT_FOUND, **REFUSED})
def shorten_movement_authority(
    vehicle_id: VehiclePath,
    body: m.MovementAuthorityEnd,
    rbc: RbcDep,
    separation: SeparationDep,
    user: AdminUser,
    trail: AuditDep,
) -> MovementAuthorityPublic:
    """Move the EoA back; refused (409) if it would fall at or behind the vehicle's front end,
    or when the RBC separates the trains (it shortens the MAs itself)."""
    request = body.model_dump(mode="json")

    def shorten() -> m.MovementAuthorityMessage:
        _manual_change_refused(separation)
        return rbc.shorten(vehicle_id, body)

    message = _changed(trail, user, vehicle_id, "rbc.ma_shorten", request, shorten)
    return _public(rbc, message)


@router.delete("/{vehicle_id}/ma", responses={**NOT_FOUND, **REFUSED})
def revoke_movement_authority(
    vehicle_id: VehiclePath,
    rbc: RbcDep,
    separation: SeparationDep,
    user: AdminUser,
    trail: AuditDep,
) -> MovementAuthorityPublic:
    """Revoke the vehicle's MA (admin only); the onboard applies it as an emergency stop."""
    message = _changed(trail, user, vehicle_id, "rbc.ma_revoke", {}, lambda: rbc.revoke(vehicle_id))
    if separation is not None:
        separation.forget_route(vehicle_id)
    return _public(rbc, message)


@router.get("/{vehicle_id}/tsr")
def read_speed_restrictions(
    vehicle_id: VehiclePath, rbc: RbcDep, _user: ObserverUser
) -> list[m.SpeedRestrictionMessage]:
    """The TSRs in force for the vehicle, in the order they were put in force (kept across a
    restart of the trackside)."""
    return list(rbc.restrictions(vehicle_id))


@router.post("/{vehicle_id}/tsr", status_code=status.HTTP_201_CREATED, responses=REFUSED)
def issue_speed_restriction(
    vehicle_id: VehiclePath,
    body: SpeedRestrictionCreate,
    rbc: RbcDep,
    user: AdminUser,
    trail: AuditDep,
) -> m.SpeedRestrictionMessage:
    """Send a temporary speed restriction to the vehicle (admin only)."""
    request = body.model_dump(mode="json")
    with trail.action(user.username, "rbc.tsr_issue", vehicle_id=vehicle_id, request=request):
        message = speed_restriction(
            vehicle_id,
            restriction_id=body.id,
            line_id=body.line_id,
            start_m=body.start_m,
            end_m=body.end_m,
            speed_mps=body.speed_kmh * MPS_PER_KMH,
        )
        rbc.restrict_speed(vehicle_id, message)
    return message


@router.delete("/{vehicle_id}/tsr/{restriction_id}", responses=REFUSED)
def revoke_speed_restriction(
    vehicle_id: VehiclePath,
    restriction_id: Annotated[str, Path(max_length=64)],
    line_id: str,
    start_m: float,
    end_m: float,
    rbc: RbcDep,
    user: AdminUser,
    trail: AuditDep,
) -> m.SpeedRestrictionMessage:
    """Revoke a temporary speed restriction on the vehicle (admin only)."""
    request = {"id": restriction_id, "line_id": line_id, "start_m": start_m, "end_m": end_m}
    with trail.action(user.username, "rbc.tsr_revoke", vehicle_id=vehicle_id, request=request):
        message = speed_restriction(
            vehicle_id,
            restriction_id=restriction_id,
            line_id=line_id,
            start_m=start_m,
            end_m=end_m,
            speed_mps=None,
        )
        rbc.restrict_speed(vehicle_id, message)
    return message
