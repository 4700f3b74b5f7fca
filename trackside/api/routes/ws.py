"""Live fleet telemetry over WebSocket.

The browser passes its bearer token as the ``token`` query parameter (browsers cannot set headers
on WebSockets). Frames coalesce: a slow browser gets the newest fleet state, never a backlog, and
never slows the Zenoh bridge.
"""

from __future__ import annotations

import asyncio
import contextlib

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from sqlalchemy.orm import Session, sessionmaker

from trackside.api.schemas import VehiclePublic
from trackside.bridge import ZenohBridge
from trackside.errors import AuthenticationError
from trackside.services import users

router = APIRouter(prefix="/ws", tags=["live"])

POLICY_VIOLATION = 1008
HEARTBEAT_S = 1.0


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
    factory: sessionmaker[Session] = app.state.session_factory
    token = websocket.query_params.get("token")
    if not await asyncio.to_thread(_authorised, factory, token):
        await websocket.close(code=POLICY_VIOLATION, reason="not authenticated")
        return
    await websocket.accept()
    bridge: ZenohBridge = app.state.bridge
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
            vehicles = [VehiclePublic.from_snapshot(s).model_dump() for s in bridge.fleet()]
            await websocket.send_json({"type": "fleet", "vehicles": vehicles})
            await asyncio.sleep(period_s)
    except WebSocketDisconnect:
        pass
    finally:
        bridge.remove_listener(on_change)
