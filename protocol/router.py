"""``ato router``: a Zenoh router in a Python session, so no separate binary is needed.

Sessions of every ``ato`` process connect to one or more routers; routers can connect to each
other (``connect``) so that the system spans several machines.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Mapping, Sequence
from typing import Any

from protocol.zenoh_config import DEFAULT_ROUTER_ENDPOINT, TlsFiles, ZenohSettings, open_session

__all__ = ["run_router"]

_log = logging.getLogger(__name__)


def run_router(
    stop: threading.Event,
    *,
    listen: Sequence[str] = (DEFAULT_ROUTER_ENDPOINT,),
    connect: Sequence[str] = (),
    ready: threading.Event | None = None,
    tls: TlsFiles | None = None,
    access_control: Mapping[str, Any] | None = None,
) -> None:
    """Run a Zenoh router until ``stop`` is set.

    Parameters
    ----------
    stop
        Set it to close the router.
    listen
        Endpoints the router accepts sessions on.
    connect
        Other routers to join, for multi-machine set-ups.
    ready
        Set once the router listens.
    tls, access_control
        The router's TLS material and its access control (``protocol.access``).
    """
    settings = ZenohSettings(
        mode="router",
        listen=tuple(listen),
        connect=tuple(connect),
        tls=tls,
        access_control=access_control,
    )
    with open_session(settings) as session:
        _log.info("zenoh router %s listening on %s", session.zid(), ", ".join(listen))
        if ready is not None:
            ready.set()
        stop.wait()
    _log.info("zenoh router closed")
