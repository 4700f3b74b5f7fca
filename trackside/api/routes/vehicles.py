"""Vehicles: which are alive and their status; holding one; commanding it; its history."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Path, Query, Request, Response, status
from sqlalchemy.orm import Session, sessionmaker

from protocol import messages as m
from protocol.units import MPS_PER_KMH
from trackside.api.deps import (
    AuditDep,
    BridgeDep,
    CommandsDep,
    DriverUser,
    ObserverUser,
    SessionDep,
    SettingsDep,
    SimulatedDep,
)
from trackside.api.schemas import (
    CommandAckPublic,
    ConfirmationKind,
    ConfirmRequest,
    EmptyRequest,
    EventPublic,
    HoldPublic,
    JourneyProfileAckPublic,
    JourneyProfileRequest,
    SkipStopRequest,
    TargetSpeedRequest,
    TelemetryPublic,
    TrainHoldRequest,
    VehiclePublic,
)
from trackside.services import history, holds
from trackside.services.fleet_list import FleetListCache, fleet_json

__all__ = ["router"]

router = APIRouter(prefix="/vehicles", tags=["vehicles"])

VehiclePath = Annotated[
    str, Path(pattern=r"^[A-Za-z0-9_-]{1,32}$", description="Vehicle id", examples=["URV1"])
]
COMMAND_ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"description": "The vehicle is not alive"},
    409: {"description": "The caller does not hold the vehicle (the detail names the holder)"},
    504: {"description": "The vehicle did not answer in time"},
}


@router.get("", response_model=list[VehiclePublic])
def list_vehicles(
    request: Request,
    bridge: BridgeDep,
    simulated: SimulatedDep,
    _user: ObserverUser,
) -> Response:
    """List every vehicle seen, whether alive, its holder and the end of their lease, and the
    latest status of the alive ones (as of at most one status period and one build ago:
    :mod:`trackside.services.fleet_list`)."""
    factory: sessionmaker[Session] = request.app.state.session_factory

    def build() -> bytes:  # on its own session: it may run after the request
        with factory() as db:
            return fleet_json(bridge.fleet(), holds.holders(db), simulated)

    cache: FleetListCache = request.app.state.fleet_list
    return Response(cache.get(holds.changes(), build), media_type="application/json")


@router.get("/{vehicle_id}", responses={404: {"description": "Never seen"}})
def read_vehicle(
    vehicle_id: VehiclePath,
    bridge: BridgeDep,
    db: SessionDep,
    simulated: SimulatedDep,
    _user: ObserverUser,
) -> VehiclePublic:
    """One vehicle, alive or not, with its holder and its latest status when alive."""
    snapshot = bridge.snapshot(vehicle_id)
    if snapshot is None:
        raise HTTPException(status_code=status.HTTP_404_NOT_FOUND, detail="no such vehicle")
    hold = holds.holder(db, vehicle_id)
    return VehiclePublic.from_snapshot(
        snapshot,
        holder=None if hold is None else hold.username,
        hold_expires_at=None if hold is None else holds.expires_at(hold),
        simulated_operator=vehicle_id in simulated,
    )


# -- holding -----------------------------------------------------------------------------------


@router.post("/{vehicle_id}/select", responses={404: {}, 409: {}})
def select_vehicle(
    vehicle_id: VehiclePath,
    bridge: BridgeDep,
    db: SessionDep,
    settings: SettingsDep,
    user: DriverUser,
    trail: AuditDep,
) -> HoldPublic:
    """Hold the vehicle: from now on only this user's commands reach it, until the lease ends
    (renewed by selecting again, by each command and while the user's console is connected)."""
    with trail.action(user.username, "select", vehicle_id=vehicle_id):
        if bridge.snapshot(vehicle_id) is None:
            raise HTTPException(status_code=status.HTTP_404_NOT_FOUND, detail="no such vehicle")
        hold = holds.select_vehicle(db, vehicle_id, user, lease_s=settings.hold_lease_s)
    return HoldPublic(
        vehicle_id=vehicle_id,
        holder=hold.username,
        since=hold.since,
        expires_at=holds.expires_at(hold),
    )


@router.post("/{vehicle_id}/release", responses={409: {}})
def release_vehicle(
    vehicle_id: VehiclePath, db: SessionDep, user: DriverUser, trail: AuditDep
) -> HoldPublic:
    """Give the vehicle up (an admin may release anyone's hold)."""
    with trail.action(user.username, "release", vehicle_id=vehicle_id):
        holds.release(db, vehicle_id, user)
    return HoldPublic(vehicle_id=vehicle_id, holder=None)


# -- commands ----------------------------------------------------------------------------------


def _send(
    commands: CommandsDep, user: DriverUser, vehicle_id: str, body: m.CommandBody
) -> CommandAckPublic:
    return CommandAckPublic.from_ack(commands.send(user, vehicle_id, body))


@router.post("/{vehicle_id}/engage", responses=COMMAND_ERRORS)
def engage(
    vehicle_id: VehiclePath,
    commands: CommandsDep,
    user: DriverUser,
    _body: EmptyRequest | None = None,
) -> CommandAckPublic:
    """Engage automatic driving (AD)."""
    return _send(commands, user, vehicle_id, m.EngageCommand())


@router.post("/{vehicle_id}/disengage", responses=COMMAND_ERRORS)
def disengage(
    vehicle_id: VehiclePath,
    commands: CommandsDep,
    user: DriverUser,
    _body: EmptyRequest | None = None,
) -> CommandAckPublic:
    """Disengage automatic driving."""
    return _send(commands, user, vehicle_id, m.DisengageCommand())


@router.post("/{vehicle_id}/rd-target-speed", responses=COMMAND_ERRORS)
def rd_target_speed(
    vehicle_id: VehiclePath, body: TargetSpeedRequest, commands: CommandsDep, user: DriverUser
) -> CommandAckPublic:
    """Remote driving: the speed to hold [km/h]."""
    command = m.RemoteDrivingTargetCommand(target_speed_mps=body.target_speed_kmh * MPS_PER_KMH)
    return _send(commands, user, vehicle_id, command)


@router.post("/{vehicle_id}/emergency-brake", responses=COMMAND_ERRORS)
def emergency_brake(
    vehicle_id: VehiclePath,
    commands: CommandsDep,
    user: DriverUser,
    _body: EmptyRequest | None = None,
) -> CommandAckPublic:
    """Ask for the emergency brake."""
    return _send(commands, user, vehicle_id, m.EmergencyBrakeCommand())


@router.post("/{vehicle_id}/confirmations/{kind}", responses=COMMAND_ERRORS)
def confirm_request(
    vehicle_id: VehiclePath,
    kind: Annotated[ConfirmationKind, Path(description="Which VC request is answered")],
    body: ConfirmRequest,
    commands: CommandsDep,
    user: DriverUser,
) -> CommandAckPublic:
    """Confirm (acknowledge, for vigilance) the VC's request of that kind and number."""
    command = m.OperatorConfirmCommand(request=kind.request, number=body.number)
    return _send(commands, user, vehicle_id, command)


@router.post("/{vehicle_id}/skip-stop", responses=COMMAND_ERRORS)
def skip_stop(
    vehicle_id: VehiclePath, body: SkipStopRequest, commands: CommandsDep, user: DriverUser
) -> CommandAckPublic:
    """Pass the timing point without stopping."""
    return _send(
        commands, user, vehicle_id, m.SkipStopCommand(timing_point_id=body.timing_point_id)
    )


@router.post("/{vehicle_id}/train-hold", responses=COMMAND_ERRORS)
def train_hold(
    vehicle_id: VehiclePath, body: TrainHoldRequest, commands: CommandsDep, user: DriverUser
) -> CommandAckPublic:
    """Hold the train at its next stopping point, or release the hold."""
    return _send(commands, user, vehicle_id, m.TrainHoldCommand(hold=body.hold))


@router.post("/{vehicle_id}/journey-profile", responses=COMMAND_ERRORS)
def send_journey_profile(
    vehicle_id: VehiclePath,
    body: JourneyProfileRequest,
    commands: CommandsDep,
    user: DriverUser,
) -> JourneyProfileAckPublic:
    """Send a stored journey to a vehicle as its journey profile, and answer with the vehicle's
    acknowledgement or rejection; 504 when the vehicle does not answer in time, 409 when the
    caller does not hold it or it has no open session, or when its plan conflicts with another
    train's and the planner cannot clear it, 404 for an unknown journey. A journey the planner
    delayed is stored as its next version, the one sent and answered."""
    sent = commands.send_journey_profile(
        user, vehicle_id, body.journey_id, body.version, body.timeout_s
    )
    return JourneyProfileAckPublic.from_sent(sent)


# -- history -----------------------------------------------------------------------------------


@router.get("/{vehicle_id}/events")
def read_events(
    vehicle_id: VehiclePath,
    db: SessionDep,
    _user: ObserverUser,
    limit: Annotated[int, Query(ge=1, le=10_000)] = 200,
) -> list[EventPublic]:
    """The vehicle's newest events, newest last."""
    return [EventPublic.from_row(row) for row in history.events(db, vehicle_id, limit=limit)]


@router.get("/{vehicle_id}/telemetry")
def read_telemetry(
    vehicle_id: VehiclePath,
    db: SessionDep,
    _user: ObserverUser,
    since_s: Annotated[float | None, Query(ge=0.0, le=1e9, allow_inf_nan=False)] = None,
    limit: Annotated[int, Query(ge=1, le=100_000)] = 3600,
) -> list[TelemetryPublic]:
    """The vehicle's 1 Hz status history, from simulated time ``since_s`` on, oldest first."""
    rows = history.telemetry(db, vehicle_id, since_s=since_s, limit=limit)
    return [TelemetryPublic.from_row(row) for row in rows]
