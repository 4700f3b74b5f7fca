"""Attacks on the Zenoh links of a deployment with TLS and access control (issue 20).

One real router listens on a loopback ``tls/`` endpoint with the deployment's access control;
the trackside ``ts1`` and the vehicles ``URV1`` and ``URV2`` connect with certificates of the
deployment's CA. Each test plays an outsider or a vehicle overstepping its own key space.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path

import pytest
import zenoh

from deploy.pki import Role, init_ca, issue
from deploy.ports import free_tcp_port
from protocol import TransportError, ZenohSettings, open_session
from protocol.access import access_control
from protocol.router import run_router
from protocol.zenoh_config import TlsFiles

pytestmark = pytest.mark.e2e

HEARD_S = 1.5
"""How long a message allowed through takes at most on loopback [s] (tens of ms in practice)."""


def _files(directory: Path, name: str) -> TlsFiles:
    return TlsFiles(
        ca=str(directory / "ca.pem"),
        certificate=str(directory / f"{name}.pem"),
        key=str(directory / f"{name}.key"),
    )


class Deployment:
    """A CA, a router with the deployment's access control, and sessions of its parties."""

    def __init__(self, directory: Path, stack: ExitStack) -> None:
        self.directory, self._stack = directory, stack
        init_ca(directory)
        issue(directory, "router", Role.ROUTER)
        issue(directory, "ts1", Role.TRACKSIDE)
        for vehicle in ("URV1", "URV2"):
            issue(directory, vehicle, Role.VEHICLE)
        self.endpoint = f"tls/127.0.0.1:{free_tcp_port()}"
        stop, ready = threading.Event(), threading.Event()
        router = threading.Thread(
            target=run_router,
            args=(stop,),
            kwargs={
                "listen": (self.endpoint,),
                "ready": ready,
                "tls": _files(directory, "router"),
                "access_control": access_control(vehicles=["URV1", "URV2"], tracksides=["ts1"]),
            },
            daemon=True,
        )
        router.start()
        stack.callback(router.join, 5.0)
        stack.callback(stop.set)
        assert ready.wait(10.0)

    def session(self, name: str, *, tls: TlsFiles | None = None) -> zenoh.Session:
        files = tls if tls is not None else _files(self.directory, name)
        settings = ZenohSettings(mode="client", connect=(self.endpoint,), tls=files)
        return self._stack.enter_context(open_session(settings, connect_timeout_s=5.0))


@pytest.fixture
def deployment(tmp_path: Path) -> Iterator[Deployment]:
    with ExitStack() as stack:
        yield Deployment(tmp_path / "pki", stack)


def _heard(session: zenoh.Session, key: str) -> queue.SimpleQueue[str]:
    heard: queue.SimpleQueue[str] = queue.SimpleQueue()
    session.declare_subscriber(key, lambda sample: heard.put(str(sample.key_expr)))
    return heard


def _settle() -> None:
    time.sleep(0.3)  # declarations reach the router and back


def test_a_vehicle_publishes_under_its_own_id_and_the_trackside_hears_it(
    deployment: Deployment,
) -> None:
    trackside, urv1 = deployment.session("ts1"), deployment.session("URV1")
    heard = _heard(trackside, "ato/ob/*/status")
    # A declared publisher, as the stack's: it drops what no subscriber it knows of matches, so
    # the trackside's declaration for every vehicle must reach the vehicle.
    publisher = urv1.declare_publisher("ato/ob/URV1/status")
    _settle()
    publisher.put(b"{}")
    assert heard.get(timeout=HEARD_S) == "ato/ob/URV1/status"


def test_a_vehicle_cannot_publish_as_another(deployment: Deployment) -> None:
    trackside, urv2 = deployment.session("ts1"), deployment.session("URV2")
    heard = _heard(trackside, "ato/ob/**")
    _settle()
    urv2.put("ato/ob/URV1/status", b"{}")
    urv2.put("ato/ob/URV2/status", b"{}")  # its own gets through: the link is up
    assert heard.get(timeout=HEARD_S) == "ato/ob/URV2/status"
    time.sleep(0.3)
    assert heard.empty()


def test_a_vehicle_cannot_command_another(deployment: Deployment) -> None:
    trackside = deployment.session("ts1")
    urv1, urv2 = deployment.session("URV1"), deployment.session("URV2")
    asked: list[str] = []

    def answer(query: zenoh.Query) -> None:
        asked.append(str(query.key_expr))
        query.reply(query.key_expr, b"ok")

    urv1.declare_queryable("ato/ob/URV1/command", answer)
    _settle()
    assert list(urv2.get("ato/ob/URV1/command", timeout=1.0)) == []
    assert asked == []
    replies = [r.ok for r in trackside.get("ato/ob/URV1/command", timeout=2.0)]
    assert [r.payload.to_bytes() for r in replies if r is not None] == [b"ok"]


def test_a_vehicle_cannot_publish_an_ma_or_impersonate_the_trackside(
    deployment: Deployment,
) -> None:
    trackside, urv1, urv2 = (deployment.session(n) for n in ("ts1", "URV1", "URV2"))
    authorities = _heard(urv1, "ato/ts/rbc/URV1/ma")
    tracksides: queue.SimpleQueue[str] = queue.SimpleQueue()
    trackside.liveliness().declare_subscriber(
        "ato/alive/**", lambda sample: tracksides.put(str(sample.key_expr))
    )
    _settle()
    urv2.put("ato/ts/rbc/URV1/ma", b"{}")
    urv2.liveliness().declare_token("ato/alive/ts/fake")
    urv2.liveliness().declare_token("ato/alive/ob/FAKE1")
    time.sleep(0.5)
    assert authorities.empty()
    assert tracksides.empty()
    trackside.put("ato/ts/rbc/URV1/ma", b"{}")
    assert authorities.get(timeout=HEARD_S) == "ato/ts/rbc/URV1/ma"


def test_a_peer_without_a_certificate_of_the_ca_cannot_open_a_session(
    deployment: Deployment, tmp_path: Path
) -> None:
    other = tmp_path / "other-ca"
    init_ca(other, name="an attacker's CA")
    issue(other, "URV1", Role.VEHICLE)  # the right name, the wrong CA
    with pytest.raises(TransportError):
        deployment.session("URV1", tls=_files(other, "URV1"))
    plain = ZenohSettings(mode="client", connect=(deployment.endpoint.replace("tls/", "tcp/"),))
    with pytest.raises(TransportError), open_session(plain, connect_timeout_s=2.0):
        pass
