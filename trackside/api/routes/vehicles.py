"""Vehicles: which are alive, and their latest status."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, status

from trackside.api.deps import BridgeDep, ObserverUser
from trackside.api.schemas import VehiclePublic

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
