"""What the recorder kept: each vehicle's events and its 1 Hz telemetry history."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from trackside.models import TelemetrySample, VehicleEvent

__all__ = ["events", "telemetry"]


def events(db: Session, vehicle_id: str, *, limit: int) -> list[VehicleEvent]:
    """The vehicle's newest ``limit`` events, oldest first."""
    query = select(VehicleEvent).where(VehicleEvent.vehicle_id == vehicle_id)
    rows = list(db.scalars(query.order_by(VehicleEvent.id.desc()).limit(limit)))
    rows.reverse()
    return rows


def telemetry(
    db: Session, vehicle_id: str, *, since_s: float | None, limit: int
) -> list[TelemetrySample]:
    """The vehicle's samples in the order received, from simulated time ``since_s`` on (all of
    them when None), at most ``limit`` (the newest)."""
    query = select(TelemetrySample).where(TelemetrySample.vehicle_id == vehicle_id)
    if since_s is not None:
        query = query.where(TelemetrySample.sim_time_s >= since_s)
    rows = list(db.scalars(query.order_by(TelemetrySample.id.desc()).limit(limit)))
    rows.reverse()
    return rows
