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
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import zenoh

from protocol._exceptions import TransportError

__all__ = [
    "DEFAULT_ROUTER_ENDPOINT",
    "TlsFiles",
    "ZenohSettings",
    "open_session",
    "zenoh_config",
]

DEFAULT_ROUTER_ENDPOINT = "tcp/127.0.0.1:7447"
MAX_LEASE_MS = 1000
CONNECT_RETRY_S = 0.25

Mode = Literal["peer", "client", "router"]

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TlsFiles:
    """A party's TLS material (PEM files): the deployment's CA, its certificate and its key.

    With them every link is TLS with mutual authentication: the party presents its certificate
    whether it listens or connects, and accepts only peers whose certificate the CA signed
    (``ato pki``, docs/security.md)."""

    ca: str
    certificate: str
    key: str

    @classmethod
    def of(cls, directory: str | Path, name: str) -> TlsFiles:
        """Party ``name``'s files in a deployment's PKI directory: ``ca.pem``, ``NAME.pem``
        and ``NAME.key`` (as ``ato pki issue`` writes them); each must exist."""
        directory = Path(directory)
        files = cls(
            ca=str(directory / "ca.pem"),
            certificate=str(directory / f"{name}.pem"),
            key=str(directory / f"{name}.key"),
        )
        for path in (files.ca, files.certificate, files.key):
            if not Path(path).is_file():
                raise TransportError(f"no {path}: issue {name!r} with `ato pki issue {directory}`")
        return files


@dataclass(frozen=True, kw_only=True)
class ZenohSettings:
    """What a process needs to join the Zenoh network."""

    mode: Mode = "client"
    connect: tuple[str, ...] = (DEFAULT_ROUTER_ENDPOINT,)
    listen: tuple[str, ...] = ()
    lease_ms: int = MAX_LEASE_MS
    tls: TlsFiles | None = None
    access_control: Mapping[str, Any] | None = None
    """A router's ``access_control`` section (``protocol.access``); None: none."""

    def config(self) -> zenoh.Config:
        return zenoh_config(
            mode=self.mode,
            connect=self.connect,
            listen=self.listen,
            lease_ms=self.lease_ms,
            tls=self.tls,
            access_control=self.access_control,
        )


def zenoh_config(
    *,
    mode: Mode,
    connect: Sequence[str] = (),
    listen: Sequence[str] = (),
    lease_ms: int = MAX_LEASE_MS,
    tls: TlsFiles | None = None,
    access_control: Mapping[str, Any] | None = None,
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
    tls
        The party's TLS material: every endpoint must then be ``tls/``, and links are mutually
        authenticated. Without it endpoints must be ``tcp/`` (insecure: for debugging only).
    access_control
        The ``access_control`` section of a router's configuration.
    """
    if not 0 < lease_ms <= MAX_LEASE_MS:
        raise ValueError(f"link lease must be in (0, {MAX_LEASE_MS}] ms, got {lease_ms}")
    if mode == "client" and not connect:
        raise ValueError("a client session needs at least one endpoint to connect to")
    for endpoint in (*connect, *listen):
        if "/" not in endpoint:
            raise ValueError(f"endpoint {endpoint!r} lacks a protocol, as in tcp/127.0.0.1:7447")
        scheme = endpoint.split("/", 1)[0]
        if (scheme == "tls") != (tls is not None):
            raise ValueError(
                f"endpoint {endpoint!r}: tls/ endpoints need TLS files, and TLS files need "
                "tls/ endpoints"
            )
    document: dict[str, Any] = {
        "mode": mode,
        "connect": {"endpoints": list(connect)},
        "listen": {"endpoints": list(listen)},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
        "transport": {"link": {"tx": {"lease": lease_ms, "keep_alive": 4}}},
        "adminspace": {"enabled": mode == "router"},
    }
    if tls is not None:
        document["transport"]["link"]["tls"] = _tls_section(tls)
    if access_control is not None:
        document["access_control"] = dict(access_control)
    try:
        return zenoh.Config.from_json5(json.dumps(document))
    except zenoh.ZError as exc:
        raise TransportError(f"invalid Zenoh configuration: {exc}") from exc


def _tls_section(tls: TlsFiles) -> dict[str, Any]:
    """Mutual authentication: the party's certificate whether it listens or connects, the
    peer's checked against the CA, and a listener's name against the endpoint's host."""
    return {
        "root_ca_certificate": tls.ca,
        "enable_mtls": True,
        "listen_certificate": tls.certificate,
        "listen_private_key": tls.key,
        "connect_certificate": tls.certificate,
        "connect_private_key": tls.key,
        "verify_name_on_connect": True,
    }


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
