"""Live telemetry over WebSocket: the fleet, one vehicle's status and events, the console's
session.

Browsers cannot set headers on WebSockets, and a URL ends up in logs and histories, so the
bearer token comes in the first message after the socket opens, ``{"type": "auth", "token":
"..."}``, within :data:`AUTH_DEADLINE_S`; a missing, late or invalid one, or a token in the
URL, closes the socket with a policy violation (1008; the console then stops reconnecting).
While a socket is open it renews its user's vehicle holds every third of a lease, and checks
that the token still holds (a revoked token, or its user disabled, closes it with 1008): a
console left open keeps its holds, one closed or crashed loses them when the lease ends
(``trackside.services.holds``).

Frames coalesce: a slow browser gets the newest fleet state or vehicle status, never a backlog,
and never slows the Zenoh bridge; a vehicle's events queue up to a bound (see
``trackside.live``).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
from datetime import datetime
from typing import Any

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from sqlalchemy.orm import Session, sessionmaker

from trackside.bridge import ZenohBridge
from trackside.errors import AuthenticationError
from trackside.live import LiveHub
from trackside.services import holds, users
from trackside.services.fleet_list import fleet_frame
from trackside.simulated_operator import SimulatedOperatorThread

__all__ = ["AUTH_DEADLINE_S", "POLICY_VIOLATION", "router"]

router = APIRouter(prefix="/ws", tags=["live"])

POLICY_VIOLATION = 1008
AUTH_DEADLINE_S = 5.0
"""How long a new socket has to send its token [s]."""
HEARTBEAT_S = 1.0
HOLDER_REFRESH_S = 1.0

Holds = dict[str, tuple[str, datetime]]
"""Vehicle id → (holder, end of the lease)."""


class Viewer:
    """The authenticated user of one socket: renews their holds while it is open."""

    def __init__(self, websocket: WebSocket, token: str, username: str) -> None:
        self.username = username
        self._token = token
        self._factory: sessionmaker[Session] = websocket.app.state.session_factory
        self._lease_s: float = websocket.app.state.settings.hold_lease_s
        self.renew_period_s = self._lease_s / 3.0
        self._renew_at = 0.0

    async def keep(self) -> bool:
        """Renew the user's holds when a third of a lease has passed since the last time;
        False once the token no longer holds (revoked, expired, user disabled)."""
        loop = asyncio.get_running_loop()
        if loop.time() < self._renew_at:
            return True
        self._renew_at = loop.time() + self.renew_period_s
        return await asyncio.to_thread(_renew, self._factory, self._token, self._lease_s)


def _renew(factory: sessionmaker[Session], token: str, lease_s: float) -> bool:
    with factory() as db, db.begin():
        try:
            user = users.resolve_token(db, token)
        except AuthenticationError:
            return False
        holds.renew_all(db, user.username, lease_s=lease_s)
    return True


def _username(factory: sessionmaker[Session], token: str) -> str | None:
    with factory() as db, db.begin():
        try:
            return users.resolve_token(db, token).username
        except AuthenticationError:
            return None


async def _refuse(websocket: WebSocket, reason: str) -> None:
    with contextlib.suppress(RuntimeError, WebSocketDisconnect):
        await websocket.close(code=POLICY_VIOLATION, reason=reason)


async def _first_token(websocket: WebSocket) -> str | None:
    """The token of the socket's first message, or None when it sends none in time (or
    leaves)."""
    try:
        message = await asyncio.wait_for(websocket.receive(), timeout=AUTH_DEADLINE_S)
    except TimeoutError:
        return None
    if message["type"] != "websocket.receive" or not message.get("text"):
        return None
    try:
        frame: Any = json.loads(message["text"])
    except ValueError:
        return None
    if not isinstance(frame, dict) or frame.get("type") != "auth":
        return None
    token = frame.get("token")
    return token if isinstance(token, str) and token else None


async def authenticate(websocket: WebSocket) -> Viewer | None:
    """Accept the socket and read its token from the first message; the socket's viewer, or
    None once the socket is closed with a policy violation (no, late or invalid token, or a
    token in the URL)."""
    await websocket.accept()
    if "token" in websocket.query_params:
        await _refuse(websocket, "no token in the URL: send it as the first message")
        return None
    token = await _first_token(websocket)
    if token is None:
        await _refuse(websocket, "not authenticated: send {type: auth, token} first")
        return None
    factory: sessionmaker[Session] = websocket.app.state.session_factory
    username = await asyncio.to_thread(_username, factory, token)
    if username is None:
        await _refuse(websocket, "not authenticated")
        return None
    viewer = Viewer(websocket, token, username)
    await viewer.keep()
    return viewer


def _holders(factory: sessionmaker[Session]) -> Holds:
    with factory() as db:
        return holds.holders(db)


def _hold(factory: sessionmaker[Session], vehicle_id: str) -> tuple[str, datetime] | None:
    """The vehicle's holder and the end of their lease, if it is held."""
    with factory() as db:
        hold = holds.holder(db, vehicle_id)
        return None if hold is None else (hold.username, holds.expires_at(hold))


def _fleet_frame(app: Any, held: Holds) -> str:
    bridge: ZenohBridge = app.state.bridge
    operator: SimulatedOperatorThread | None = app.state.simulated_operator
    simulated = frozenset() if operator is None else operator.operator.vehicles
    return fleet_frame(bridge.fleet(), held, simulated)


@router.websocket("/fleet")
async def fleet_stream(websocket: WebSocket) -> None:
    """Push the fleet (as in ``GET /vehicles``) on every change, at most every push period."""
    app = websocket.app
    viewer = await authenticate(websocket)
    if viewer is None:
        return
    factory: sessionmaker[Session] = app.state.session_factory
    bridge: ZenohBridge = app.state.bridge
    period_s: float = app.state.settings.fleet_push_period_s
    loop = asyncio.get_running_loop()
    changed = asyncio.Event()

    def on_change() -> None:
        loop.call_soon_threadsafe(changed.set)

    bridge.add_listener(on_change)
    try:
        while await viewer.keep():
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(changed.wait(), timeout=HEARTBEAT_S)
            changed.clear()
            held = await asyncio.to_thread(_holders, factory)
            await websocket.send_text(_fleet_frame(app, held))
            await asyncio.sleep(period_s)
        await _refuse(websocket, "token no longer valid")
    except WebSocketDisconnect:
        pass
    finally:
        bridge.remove_listener(on_change)


def _status_frame(
    status: Any, hold: tuple[str, datetime] | None, simulated: bool
) -> dict[str, Any]:
    return {
        "type": "status",
        "status": status.model_dump(mode="json"),
        "holder": None if hold is None else hold[0],
        "hold_expires_at": None if hold is None else hold[1].isoformat(),
        "simulated_operator": simulated,
    }


@router.websocket("/vehicles/{vehicle_id}")
async def vehicle_stream(websocket: WebSocket, vehicle_id: str) -> None:
    """Push the vehicle's status (newest only) and its events as they come."""
    app = websocket.app
    viewer = await authenticate(websocket)
    if viewer is None:
        return
    factory: sessionmaker[Session] = app.state.session_factory
    hub: LiveHub = app.state.live
    operator: SimulatedOperatorThread | None = app.state.simulated_operator
    simulated = operator is not None and vehicle_id in operator.operator.vehicles
    feed = hub.open(vehicle_id, asyncio.get_running_loop())
    loop = asyncio.get_running_loop()
    hold = await asyncio.to_thread(_hold, factory, vehicle_id)
    holder_at = loop.time()
    try:
        while await viewer.keep():
            await feed.wait(HEARTBEAT_S)
            if loop.time() - holder_at >= HOLDER_REFRESH_S:
                hold = await asyncio.to_thread(_hold, factory, vehicle_id)
                holder_at = loop.time()
            status, events = feed.take()
            for event in events:
                await websocket.send_json({"type": "event", "event": event})
            if status is not None:
                await websocket.send_json(_status_frame(status, hold, simulated))
        await _refuse(websocket, "token no longer valid")
    except WebSocketDisconnect:
        pass
    finally:
        hub.close(vehicle_id, feed)


@router.websocket("/session")
async def session_stream(websocket: WebSocket) -> None:
    """The console's presence, open whatever the view: renews the user's holds while it
    lasts, and pushes them (``{"type": "holds", "holds": {vehicle: end of lease}}``) each
    time."""
    viewer = await authenticate(websocket)
    if viewer is None:
        return
    factory: sessionmaker[Session] = websocket.app.state.session_factory
    sent: dict[str, str] | None = None
    try:
        while await viewer.keep():
            held = await asyncio.to_thread(_holders, factory)
            mine = {
                vehicle: until.isoformat()
                for vehicle, (holder, until) in held.items()
                if holder == viewer.username
            }
            if mine != sent:
                await websocket.send_json({"type": "holds", "holds": mine})
                sent = mine
            wait_s = min(HEARTBEAT_S, viewer.renew_period_s)
            try:  # the console sends nothing more: this only notices it leaving
                message = await asyncio.wait_for(websocket.receive(), timeout=wait_s)
            except TimeoutError:
                continue
            if message["type"] == "websocket.disconnect":
                return
        await _refuse(websocket, "token no longer valid")
    except WebSocketDisconnect:
        pass
