"""Zenoh configuration and sessions for every ``ato`` process.

Every configuration built here disables multicast scouting and gossip, names its endpoints
explicitly, and sets the link lease to at most 1 s, so that a frozen process is noticed in under a
second and nothing leaves the endpoints it was given (ARCHITECTURE.md, "Messages").

Processes run as ``client`` sessions of one or more ``ato router``: with gossip off, peers that
only meet through a router do not see each other's liveliness tokens, whereas clients route
everything through the router and reconnect on their own when it restarts. A client cannot open
while no router answers, so :func:`open_session` retries until ``connect_timeout_s``; start order
then does not matter. Tests may pair two peers directly, one listening, one connecting.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Literal

import zenoh

from protocol._exceptions import TransportError

__all__ = ["DEFAULT_ROUTER_ENDPOINT", "ZenohSettings", "open_session", "zenoh_config"]

DEFAULT_ROUTER_ENDPOINT = "tcp/127.0.0.1:7447"
MAX_LEASE_MS = 1000
CONNECT_RETRY_S = 0.25

Mode = Literal["peer", "client", "router"]

_log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class ZenohSettings:
    """What a process needs to join the Zenoh network."""

    mode: Mode = "client"
    connect: tuple[str, ...] = (DEFAULT_ROUTER_ENDPOINT,)
    listen: tuple[str, ...] = ()
    lease_ms: int = MAX_LEASE_MS

    def config(self) -> zenoh.Config:
        return zenoh_config(
            mode=self.mode, connect=self.connect, listen=self.listen, lease_ms=self.lease_ms
        )


def zenoh_config(
    *,
    mode: Mode,
    connect: Sequence[str] = (),
    listen: Sequence[str] = (),
    lease_ms: int = MAX_LEASE_MS,
) -> zenoh.Config:
    """A Zenoh configuration with explicit endpoints and no scouting.

    Parameters
    ----------
    mode
        ``peer``, ``client`` or ``router``.
    connect, listen
        Endpoints such as ``tcp/127.0.0.1:7447``.
    lease_ms
        Link lease [ms], at most 1000; keep-alives go four times per lease.
    """
    if not 0 < lease_ms <= MAX_LEASE_MS:
        raise ValueError(f"link lease must be in (0, {MAX_LEASE_MS}] ms, got {lease_ms}")
    if mode == "client" and not connect:
        raise ValueError("a client session needs at least one endpoint to connect to")
    for endpoint in (*connect, *listen):
        if "/" not in endpoint:
            raise ValueError(f"endpoint {endpoint!r} lacks a protocol, as in tcp/127.0.0.1:7447")
    document = {
        "mode": mode,
        "connect": {"endpoints": list(connect)},
        "listen": {"endpoints": list(listen)},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
        "transport": {"link": {"tx": {"lease": lease_ms, "keep_alive": 4}}},
        "adminspace": {"enabled": mode == "router"},
    }
    try:
        return zenoh.Config.from_json5(json.dumps(document))
    except zenoh.ZError as exc:
        raise TransportError(f"invalid Zenoh configuration: {exc}") from exc


@contextmanager
def open_session(
    settings: ZenohSettings, *, connect_timeout_s: float = 30.0
) -> Iterator[zenoh.Session]:
    """Open a Zenoh session for the ``with`` block and always close it afterwards.

    A client retries until a router answers or ``connect_timeout_s`` [s] has passed.
    """
    deadline = time.monotonic() + connect_timeout_s
    while True:
        try:
            session = zenoh.open(settings.config())
            break
        except zenoh.ZError as exc:
            if settings.mode != "client" or time.monotonic() >= deadline:
                raise TransportError(f"cannot open a {settings.mode} Zenoh session: {exc}") from exc
            _log.info("no Zenoh router at %s yet; retrying", ", ".join(settings.connect))
            time.sleep(CONNECT_RETRY_S)
    _log.debug("zenoh %s session %s open", settings.mode, session.zid())
    try:
        yield session
    finally:
        session.close()
