"""Vehicles: which are alive, their latest status, and journey profiles sent to them."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, status
from pydantic import BaseModel, ConfigDict, Field

from protocol import messages as m
from trackdb.journey import journey_profile_message
from trackside.api.deps import BridgeDep, DriverUser, ObserverUser, SessionDep
from trackside.api.schemas import VehiclePublic
from trackside.services.journeys import get_journey, validate_journey

router = APIRouter(prefix="/vehicles", tags=["vehicles"])


@router.get("")
def list_vehicles(bridge: BridgeDep, _user: ObserverUser) -> list[VehiclePublic]:
    """List every vehicle seen, whether alive, and the latest status of the alive ones."""
    return [VehiclePublic.from_snapshot(snapshot) for snapshot in bridge.fleet()]


@router.get("/{vehicle_id}")
def read_vehicle(vehicle_id: str, bridge: BridgeDep, _user: ObserverUser) -> VehiclePublic:
    """One vehicle, alive or not, with its latest status when alive."""
    snapshot = bridge.snapshot(vehicle_id)
    if snapshot is None:
        raise HTTPException(status_code=status.HTTP_404_NOT_FOUND, detail="no such vehicle")
    return VehiclePublic.from_snapshot(snapshot)


class JourneyProfileRequest(BaseModel):
    """Which stored journey to send, and which version (the latest when omitted)."""

    model_config = ConfigDict(extra="forbid")

    journey_id: str = Field(min_length=1, max_length=64)
    version: int | None = Field(default=None, ge=1)
    timeout_s: float = Field(default=5.0, gt=0.0, le=30.0, description="Wait for the JPAck [s]")


class JourneyProfileAnswer(BaseModel):
    """What the vehicle answered: its JPAck (accepted, or rejected with the reason)."""

    journey_id: str
    version: int
    accepted: bool
    reason: str | None


@router.post("/{vehicle_id}/journey-profile")
def send_journey_profile(
    vehicle_id: str, body: JourneyProfileRequest, db: SessionDep, bridge: BridgeDep,
    _user: DriverUser,
) -> JourneyProfileAnswer:  # fmt: skip
    """Send a stored journey to a vehicle as its journey profile, and answer with the vehicle's
    acknowledgement or rejection; 504 when the vehicle does not answer in time, 409 when it has
    no open session."""
    snapshot = bridge.snapshot(vehicle_id)
    if snapshot is None or not snapshot.alive:
        raise HTTPException(status_code=status.HTTP_404_NOT_FOUND, detail="no such vehicle alive")
    if not bridge.session_open(vehicle_id):
        raise HTTPException(status_code=status.HTTP_409_CONFLICT, detail="no session open")
    stored = get_journey(db, body.journey_id, body.version)
    check, line_version = validate_journey(db, stored.journey)
    if not check.valid:
        raise HTTPException(
            status_code=status.HTTP_409_CONFLICT,
            detail=f"journey {body.journey_id} no longer valid on line version {line_version}",
        )
    profile = journey_profile_message(
        stored.journey, check, vehicle_id=vehicle_id, version=stored.version,
        track_data_version=line_version, status=m.JourneyProfileStatus.VALID,
    )  # fmt: skip
    ack = bridge.send_journey_profile(profile, timeout_s=body.timeout_s)
    if ack is None:
        raise HTTPException(
            status_code=status.HTTP_504_GATEWAY_TIMEOUT, detail="the vehicle did not answer"
        )
    return JourneyProfileAnswer(
        journey_id=ack.journey_id, version=ack.version, accepted=ack.accepted, reason=ack.reason
    )
