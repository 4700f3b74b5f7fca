"""Vehicles: which are alive and their status; holding one; commanding it; its history."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Path, Query, status
from pydantic import BaseModel, ConfigDict, Field

from protocol import messages as m
from protocol.units import MPS_PER_KMH
from trackside.api.deps import (
    BridgeDep,
    CommandsDep,
    DriverUser,
    ObserverUser,
    SessionDep,
    SimulatedDep,
)
from trackside.api.schemas import VehiclePublic
from trackside.errors import (
    ConflictError,
    NotFoundError,
    VehicleLinkError,
    VehicleTimeoutError,
)
from trackside.models import TelemetrySample, VehicleEvent
from trackside.services import audit, history, holds

router = APIRouter(prefix="/vehicles", tags=["vehicles"])

VehiclePath = Annotated[
    str, Path(pattern=r"^[A-Za-z0-9_-]{1,32}$", description="Vehicle id", examples=["URV1"])
]
COMMAND_ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"description": "The vehicle is not alive"},
    409: {"description": "The caller does not hold the vehicle (the detail names the holder)"},
    504: {"description": "The vehicle did not answer in time"},
}


@contextmanager
def _vehicle_errors() -> Iterator[None]:
    """Turn the command services' domain errors into HTTP answers."""
    try:
        yield
    except NotFoundError as exc:
        raise HTTPException(status_code=status.HTTP_404_NOT_FOUND, detail=str(exc)) from exc
    except ConflictError as exc:
        raise HTTPException(status_code=status.HTTP_409_CONFLICT, detail=str(exc)) from exc
    except VehicleTimeoutError as exc:
        raise HTTPException(status_code=status.HTTP_504_GATEWAY_TIMEOUT, detail=str(exc)) from exc
    except VehicleLinkError as exc:
        raise HTTPException(status_code=status.HTTP_502_BAD_GATEWAY, detail=str(exc)) from exc


@router.get("")
def list_vehicles(
    bridge: BridgeDep, db: SessionDep, simulated: SimulatedDep, _user: ObserverUser
) -> list[VehiclePublic]:
    """List every vehicle seen, whether alive, its holder, and the latest status of the alive
    ones."""
    held = holds.holders(db)
    return [
        VehiclePublic.from_snapshot(
            snapshot,
            holder=held[snapshot.id].username if snapshot.id in held else None,
            simulated_operator=snapshot.id in simulated,
        )
        for snapshot in bridge.fleet()
    ]


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
        simulated_operator=vehicle_id in simulated,
    )


# -- holding -----------------------------------------------------------------------------------


class HoldPublic(BaseModel):
    vehicle_id: str
    holder: str | None
    since: datetime | None = None


@router.post("/{vehicle_id}/select", responses={404: {}, 409: {}})
def select_vehicle(
    vehicle_id: VehiclePath, bridge: BridgeDep, db: SessionDep, user: DriverUser
) -> HoldPublic:
    """Hold the vehicle: from now on only this user's commands reach it (idempotent)."""
    if bridge.snapshot(vehicle_id) is None:
        raise HTTPException(status_code=status.HTTP_404_NOT_FOUND, detail="no such vehicle")
    try:
        hold = holds.select_vehicle(db, vehicle_id, user)
    except ConflictError as exc:
        raise HTTPException(status_code=status.HTTP_409_CONFLICT, detail=str(exc)) from exc
    db.add(
        audit.audit_entry(
            user=user.username,
            vehicle_id=vehicle_id,
            action="select",
            request={},
            result=audit.AuditResult.ACCEPTED,
        )
    )
    return HoldPublic(vehicle_id=vehicle_id, holder=hold.username, since=hold.since)


@router.post("/{vehicle_id}/release", responses={409: {}})
def release_vehicle(vehicle_id: VehiclePath, db: SessionDep, user: DriverUser) -> HoldPublic:
    """Give the vehicle up (an admin may release anyone's hold)."""
    try:
        holds.release(db, vehicle_id, user)
    except ConflictError as exc:
        raise HTTPException(status_code=status.HTTP_409_CONFLICT, detail=str(exc)) from exc
    db.add(
        audit.audit_entry(
            user=user.username,
            vehicle_id=vehicle_id,
            action="release",
            request={},
            result=audit.AuditResult.ACCEPTED,
        )
    )
    return HoldPublic(vehicle_id=vehicle_id, holder=None)


# -- commands ----------------------------------------------------------------------------------


class CommandAnswer(BaseModel):
    """What the vehicle answered: accepted for execution, or refused with the reason."""

    vehicle_id: str
    command_id: int
    accepted: bool
    reason: str | None

    @classmethod
    def from_ack(cls, ack: m.CommandAck) -> CommandAnswer:
        return cls(
            vehicle_id=ack.vehicle_id,
            command_id=ack.command_id,
            accepted=ack.accepted,
            reason=ack.reason,
        )


class EmptyRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")


class TargetSpeedRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    target_speed_kmh: float = Field(ge=0.0, le=360.0, allow_inf_nan=False, description="[km/h]")


class ConfirmRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    number: int = Field(ge=0, le=255, description="The number of the VC request answered")


class SkipStopRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    timing_point_id: str = Field(min_length=1, max_length=64)


class TrainHoldRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    hold: bool


def _send(
    commands: CommandsDep, user: DriverUser, vehicle_id: str, body: m.CommandBody
) -> CommandAnswer:
    with _vehicle_errors():
        return CommandAnswer.from_ack(commands.send(user, vehicle_id, body))


@router.post("/{vehicle_id}/engage", responses=COMMAND_ERRORS)
def engage(
    vehicle_id: VehiclePath,
    commands: CommandsDep,
    user: DriverUser,
    _body: EmptyRequest | None = None,
) -> CommandAnswer:
    """Engage automatic driving (AD)."""
    return _send(commands, user, vehicle_id, m.EngageCommand())


@router.post("/{vehicle_id}/disengage", responses=COMMAND_ERRORS)
def disengage(
    vehicle_id: VehiclePath,
    commands: CommandsDep,
    user: DriverUser,
    _body: EmptyRequest | None = None,
) -> CommandAnswer:
    """Disengage automatic driving."""
    return _send(commands, user, vehicle_id, m.DisengageCommand())


@router.post("/{vehicle_id}/rd-target-speed", responses=COMMAND_ERRORS)
def rd_target_speed(
    vehicle_id: VehiclePath, body: TargetSpeedRequest, commands: CommandsDep, user: DriverUser
) -> CommandAnswer:
    """Remote driving: the speed to hold [km/h]."""
    command = m.RemoteDrivingTargetCommand(target_speed_mps=body.target_speed_kmh * MPS_PER_KMH)
    return _send(commands, user, vehicle_id, command)


@router.post("/{vehicle_id}/emergency-brake", responses=COMMAND_ERRORS)
def emergency_brake(
    vehicle_id: VehiclePath,
    commands: CommandsDep,
    user: DriverUser,
    _body: EmptyRequest | None = None,
) -> CommandAnswer:
    """Ask for the emergency brake."""
    return _send(commands, user, vehicle_id, m.EmergencyBrakeCommand())


def _confirm(
    kind: m.OperatorRequestKind,
    vehicle_id: str,
    body: ConfirmRequest,
    commands: CommandsDep,
    user: DriverUser,
) -> CommandAnswer:
    command = m.OperatorConfirmCommand(request=kind, number=body.number)
    return _send(commands, user, vehicle_id, command)


@router.post("/{vehicle_id}/eb-rearm", responses=COMMAND_ERRORS)
def eb_rearm(
    vehicle_id: VehiclePath, body: ConfirmRequest, commands: CommandsDep, user: DriverUser
) -> CommandAnswer:
    """Confirm the VC's EB rearm request of that number."""
    return _confirm(m.OperatorRequestKind.EB_REARM, vehicle_id, body, commands, user)


@router.post("/{vehicle_id}/etcs-isolation", responses=COMMAND_ERRORS)
def etcs_isolation(
    vehicle_id: VehiclePath, body: ConfirmRequest, commands: CommandsDep, user: DriverUser
) -> CommandAnswer:
    """Confirm the VC's ETCS isolation request of that number."""
    return _confirm(m.OperatorRequestKind.ETCS_ISOLATION, vehicle_id, body, commands, user)


@router.post("/{vehicle_id}/etcs-insertion", responses=COMMAND_ERRORS)
def etcs_insertion(
    vehicle_id: VehiclePath, body: ConfirmRequest, commands: CommandsDep, user: DriverUser
) -> CommandAnswer:
    """Confirm the VC's ETCS insertion request of that number."""
    return _confirm(m.OperatorRequestKind.ETCS_INSERTION, vehicle_id, body, commands, user)


@router.post("/{vehicle_id}/vigilance-ack", responses=COMMAND_ERRORS)
def vigilance_ack(
    vehicle_id: VehiclePath, body: ConfirmRequest, commands: CommandsDep, user: DriverUser
) -> CommandAnswer:
    """Acknowledge the VC's vigilance request of that number."""
    return _confirm(m.OperatorRequestKind.VIGILANCE, vehicle_id, body, commands, user)


@router.post("/{vehicle_id}/skip-stop", responses=COMMAND_ERRORS)
def skip_stop(
    vehicle_id: VehiclePath, body: SkipStopRequest, commands: CommandsDep, user: DriverUser
) -> CommandAnswer:
    """Pass the timing point without stopping."""
    return _send(
        commands, user, vehicle_id, m.SkipStopCommand(timing_point_id=body.timing_point_id)
    )


@router.post("/{vehicle_id}/train-hold", responses=COMMAND_ERRORS)
def train_hold(
    vehicle_id: VehiclePath, body: TrainHoldRequest, commands: CommandsDep, user: DriverUser
) -> CommandAnswer:
    """Hold the train at its next stopping point, or release the hold."""
    return _send(commands, user, vehicle_id, m.TrainHoldCommand(hold=body.hold))


class JourneyProfileRequest(BaseModel):
    """Which stored journey to send, and which version (the latest when omitted)."""

    model_config = ConfigDict(extra="forbid")

    journey_id: str = Field(min_length=1, max_length=64)
    version: int | None = Field(default=None, ge=1, le=2**31 - 1)
    timeout_s: float = Field(default=5.0, gt=0.0, le=30.0, description="Wait for the JPAck [s]")


class JourneyProfileAnswer(BaseModel):
    """What the vehicle answered: its JPAck (accepted, or rejected with the reason)."""

    journey_id: str
    version: int
    accepted: bool
    reason: str | None


@router.post("/{vehicle_id}/journey-profile", responses=COMMAND_ERRORS)
def send_journey_profile(
    vehicle_id: VehiclePath,
    body: JourneyProfileRequest,
    commands: CommandsDep,
    user: DriverUser,
) -> JourneyProfileAnswer:
    """Send a stored journey to a vehicle as its journey profile, and answer with the vehicle's
    acknowledgement or rejection; 504 when the vehicle does not answer in time, 409 when the
    caller does not hold it or it has no open session, 404 for an unknown journey."""
    with _vehicle_errors():
        ack = commands.send_journey_profile(
            user, vehicle_id, body.journey_id, body.version, body.timeout_s
        )
    return JourneyProfileAnswer(
        journey_id=ack.journey_id, version=ack.version, accepted=ack.accepted, reason=ack.reason
    )


# -- history -----------------------------------------------------------------------------------


class EventPublic(BaseModel):
    sim_time_s: float = Field(description="Onboard simulated time [s]")
    received_at: datetime
    severity: m.EventSeverity
    code: str
    text: str
    seq: int

    @classmethod
    def from_row(cls, row: VehicleEvent) -> EventPublic:
        return cls(
            sim_time_s=row.sim_time_s,
            received_at=row.received_at,
            severity=m.EventSeverity(row.severity),
            code=row.code,
            text=row.text,
            seq=row.seq,
        )


class TelemetryPublic(BaseModel):
    """One sample of the 1 Hz history (SI units)."""

    sim_time_s: float
    received_at: datetime
    position_m: float
    speed_mps: float
    traction_force_n: float
    reference_speed_mps: float | None
    permitted_speed_mps: float | None
    intervention_speed_mps: float | None
    ato_state: str
    etcs_mode: str
    sc_state: str
    eb: bool
    journey_id: str | None

    @classmethod
    def from_row(cls, row: TelemetrySample) -> TelemetryPublic:
        return cls.model_validate(row, from_attributes=True)


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
