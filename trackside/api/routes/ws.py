"""Live telemetry over WebSocket: the fleet, and one vehicle's status and events.

The browser passes its bearer token as the ``token`` query parameter (browsers cannot set headers
on WebSockets). Frames coalesce: a slow browser gets the newest fleet state or vehicle status,
never a backlog, and never slows the Zenoh bridge; a vehicle's events queue up to a bound (see
``trackside.live``).
"""

from __future__ import annotations

import asyncio
import contextlib

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from sqlalchemy.orm import Session, sessionmaker

from trackside.api.schemas import VehiclePublic
from trackside.bridge import ZenohBridge
from trackside.errors import AuthenticationError
from trackside.live import LiveHub
from trackside.services import holds, users
from trackside.simulated_operator import SimulatedOperatorThread

__all__ = ["router"]

router = APIRouter(prefix="/ws", tags=["live"])

POLICY_VIOLATION = 1008
HEARTBEAT_S = 1.0


async def _accept(websocket: WebSocket) -> bool:
    """Accept the socket if its ``token`` query parameter is a valid login; else close it with
    a policy violation (the console then stops reconnecting) and say so."""
    factory: sessionmaker[Session] = websocket.app.state.session_factory
    token = websocket.query_params.get("token")
    if not await asyncio.to_thread(_authorised, factory, token):
        await websocket.close(code=POLICY_VIOLATION, reason="not authenticated")
        return False
    await websocket.accept()
    return True


def _authorised(factory: sessionmaker[Session], token: str | None) -> bool:
    if not token:
        return False
    with factory() as db, db.begin():
        try:
            users.resolve_token(db, token)
        except AuthenticationError:
            return False
    return True


@router.websocket("/fleet")
async def fleet_stream(websocket: WebSocket) -> None:
    """Push the fleet (as in ``GET /vehicles``) on every change, at most every push period."""
    app = websocket.app
    if not await _accept(websocket):
        return
    factory: sessionmaker[Session] = app.state.session_factory
    bridge: ZenohBridge = app.state.bridge
    operator: SimulatedOperatorThread | None = app.state.simulated_operator
    simulated = frozenset() if operator is None else operator.operator.vehicles
    period_s: float = app.state.settings.fleet_push_period_s
    loop = asyncio.get_running_loop()
    changed = asyncio.Event()

    def on_change() -> None:
        loop.call_soon_threadsafe(changed.set)

    bridge.add_listener(on_change)
    try:
        while True:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(changed.wait(), timeout=HEARTBEAT_S)
            changed.clear()
            held = await asyncio.to_thread(_holders, factory)
            vehicles = [
                VehiclePublic.from_snapshot(
                    snapshot,
                    holder=held.get(snapshot.id),
                    simulated_operator=snapshot.id in simulated,
                ).model_dump(mode="json")
                for snapshot in bridge.fleet()
            ]
            await websocket.send_json({"type": "fleet", "vehicles": vehicles})
            await asyncio.sleep(period_s)
    except WebSocketDisconnect:
        pass
    finally:
        bridge.remove_listener(on_change)


HOLDER_REFRESH_S = 1.0


def _holders(factory: sessionmaker[Session]) -> dict[str, str]:
    with factory() as db:
        return {vehicle: hold.username for vehicle, hold in holds.holders(db).items()}


def _holder(factory: sessionmaker[Session], vehicle_id: str) -> str | None:
    return _holders(factory).get(vehicle_id)


@router.websocket("/vehicles/{vehicle_id}")
async def vehicle_stream(websocket: WebSocket, vehicle_id: str) -> None:
    """Push the vehicle's status (newest only) and its events as they come."""
    app = websocket.app
    if not await _accept(websocket):
        return
    factory: sessionmaker[Session] = app.state.session_factory
    hub: LiveHub = app.state.live
    operator: SimulatedOperatorThread | None = app.state.simulated_operator
    simulated = operator is not None and vehicle_id in operator.operator.vehicles
    feed = hub.open(vehicle_id, asyncio.get_running_loop())
    holder = await asyncio.to_thread(_holder, factory, vehicle_id)
    loop = asyncio.get_running_loop()
    holder_at = loop.time()
    try:
        while True:
            await feed.wait(HEARTBEAT_S)
            if loop.time() - holder_at >= HOLDER_REFRESH_S:
                holder = await asyncio.to_thread(_holder, factory, vehicle_id)
                holder_at = loop.time()
            status, events = feed.take()
            for event in events:
                await websocket.send_json({"type": "event", "event": event})
            if status is not None:
                await websocket.send_json(
                    {
                        "type": "status",
                        "status": status.model_dump(mode="json"),
                        "holder": holder,
                        "simulated_operator": simulated,
                    }
                )
    except WebSocketDisconnect:
        pass
    finally:
        hub.close(vehicle_id, feed)
