"""Commands to a vehicle over Zenoh: a query on ``ato/ob/{vehicle}/command``, answered by the
vehicle's acknowledgement, taken only when it is the addressed vehicle's answer to that command
(its vehicle id and command id; issue 20). The command comes sealed for the vehicle's session
(:meth:`trackside.bridge.ZenohBridge.command`).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

import zenoh

from protocol import PayloadError, TransportError, request
from protocol import messages as m
from protocol.registry import COMMAND

__all__ = ["check_ack", "send_command", "send_command_async"]

_log = logging.getLogger("trackside.bridge")


def send_command(session: zenoh.Session, command: m.Command, *, timeout_s: float) -> m.CommandAck:
    """Send a command and wait for the vehicle's acknowledgement. Raises
    ``protocol.RequestTimeoutError`` when none came in ``timeout_s`` of wall time, other
    ``protocol.ProtocolError`` when the answer was an error or not valid, or not the addressed
    vehicle's answer to this command."""
    ack: m.CommandAck = request(
        session, COMMAND, command, timeout_s=timeout_s, vehicle=command.vehicle_id
    )
    check_ack(command, ack)
    return ack


def send_command_async(
    session: zenoh.Session,
    command: m.Command,
    on_done: Callable[[m.CommandAck | None], None],
    *,
    timeout_s: float,
) -> None:
    """Send a command without waiting. ``on_done`` is called once, on Zenoh's thread, with
    the acknowledgement, or with None when the query ended without a valid one."""
    key = COMMAND.key(vehicle=command.vehicle_id)
    finished = threading.Event()

    def finish(ack: m.CommandAck | None) -> None:
        if finished.is_set():
            return
        finished.set()
        try:
            on_done(ack)
        except Exception:  # a consumer's bug must not kill Zenoh's thread
            _log.exception("command callback for %s failed", key)

    def on_reply(reply: zenoh.Reply) -> None:
        if reply.ok is None:
            _log.warning("%s: error reply to command %d", key, command.command_id)
            return
        try:
            ack = COMMAND.decode_reply(reply.ok.payload.to_bytes())
            check_ack(command, ack)
            finish(ack)
        except PayloadError as exc:
            _log.warning("%s: bad command reply dropped: %s", key, exc)

    try:
        session.get(
            key,
            zenoh.handlers.Callback(on_reply, lambda: finish(None)),
            payload=COMMAND.encode(command),
            timeout=timeout_s,
        )
    except zenoh.ZError as exc:
        raise TransportError(f"command on {key} failed: {exc}") from exc


def check_ack(command: m.Command, ack: m.CommandAck) -> None:
    """Raise :class:`~protocol.PayloadError` unless ``ack`` is the addressed vehicle's answer
    to ``command``."""
    if (ack.vehicle_id, ack.command_id) != (command.vehicle_id, command.command_id):
        raise PayloadError(
            f"acknowledgement of {ack.vehicle_id}'s command {ack.command_id} came back for "
            f"{command.vehicle_id}'s command {command.command_id}: dropped"
        )
