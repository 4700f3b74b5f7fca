"""The link proxy of the ``zenoh_link_loss`` fault, on real loopback sockets and Zenoh sessions."""

from __future__ import annotations

import socket
import socketserver
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from deploy.link_proxy import LinkMode, LinkProxy, LinkProxyError
from deploy.ports import loopback_endpoint
from deploy.scenario.zenoh_link import ZenohLinkFault
from protocol import ZenohSettings, declare_liveliness, open_session
from protocol.registry import ALIVE_ONBOARD, ALIVE_TRACKSIDE

QUIET_S = 0.3
"""How long a stalled connection is watched for data that must not come [s]."""


class _Echo(socketserver.BaseRequestHandler):
    def handle(self) -> None:
        try:
            while data := self.request.recv(65536):
                self.request.sendall(data)
        except OSError:
            pass  # reset by the proxy: the test is about that


@pytest.fixture
def echo() -> Iterator[tuple[str, int]]:
    server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), _Echo)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        host, port = server.server_address[:2]
        yield str(host), int(port)
    finally:
        server.shutdown()
        server.server_close()


@pytest.fixture
def proxy(echo: tuple[str, int]) -> Iterator[LinkProxy]:
    with LinkProxy(echo) as started:
        yield started


def _wait_for(condition: Callable[[], bool], timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.001)
    return True


def _connect(proxy: LinkProxy) -> socket.socket:
    return socket.create_connection(proxy.address, timeout=5.0)


def _echoes(connection: socket.socket, data: bytes) -> bool:
    connection.sendall(data)
    received = b""
    while len(received) < len(data):
        chunk = connection.recv(65536)
        if not chunk:
            break
        received += chunk
    return received == data


def _stays_quiet(connection: socket.socket) -> bool:
    connection.settimeout(QUIET_S)
    try:
        connection.recv(65536)
    except TimeoutError:
        return True
    finally:
        connection.settimeout(5.0)
    return False


def _is_refused(proxy: LinkProxy) -> bool:
    """A connection is reset, whether already while connecting or at the first read."""
    try:
        with _connect(proxy) as connection:
            return connection.recv(65536) == b""
    except ConnectionResetError:
        return True


def test_forwards_both_ways_and_counts_the_bytes(proxy: LinkProxy) -> None:
    assert proxy.endpoint == f"tcp/127.0.0.1:{proxy.address[1]}"
    payload = bytes(range(256)) * 1000
    with _connect(proxy) as connection:
        assert _echoes(connection, payload)
        assert _wait_for(lambda: proxy.stats().bytes_down == len(payload))
        stats = proxy.stats()
        assert (stats.accepted, stats.forwarded, stats.bytes_up) == (1, 1, len(payload))
        assert proxy.up
        assert stats.open_connections == 1


def test_a_silent_cut_stalls_connections_and_black_holes_new_ones(proxy: LinkProxy) -> None:
    with _connect(proxy) as connection:
        assert _echoes(connection, b"before")
        assert proxy.cut("silent") == 1
        assert not proxy.up
        # Sent while the link is quiet: it waits, as TCP holds unacknowledged segments.
        connection.sendall(b"during")
        assert _stays_quiet(connection)
        with _connect(proxy) as newcomer:
            assert _wait_for(lambda: proxy.stats().refused == 1)
            newcomer.sendall(b"hello?")
            assert _stays_quiet(newcomer)
            proxy.restore()
            # The black-holed connection is reset; the stalled one goes on where it stood.
            with pytest.raises(ConnectionResetError):
                newcomer.recv(65536)
        assert connection.recv(65536) == b"during"
        assert _echoes(connection, b"after")
    stats = proxy.stats()
    assert (stats.cuts, stats.dropped, stats.refused, stats.forwarded) == (1, 1, 1, 1)


def test_a_reset_cut_resets_connections_and_refuses_new_ones(proxy: LinkProxy) -> None:
    with _connect(proxy) as connection:
        assert _echoes(connection, b"before")
        assert proxy.cut("reset") == 1
        with pytest.raises(ConnectionResetError):
            connection.recv(65536)
    assert _wait_for(lambda: proxy.stats().open_connections == 0)
    assert _is_refused(proxy)
    proxy.restore()
    with _connect(proxy) as connection:
        assert _echoes(connection, b"after")
    stats = proxy.stats()
    assert (stats.cuts, stats.dropped, stats.refused, stats.forwarded) == (1, 1, 1, 2)


def test_a_target_that_refuses_is_passed_on_as_a_reset() -> None:
    with LinkProxy(("127.0.0.1", int(loopback_endpoint().rsplit(":", 1)[1]))) as proxy:
        assert _is_refused(proxy)
        assert _wait_for(lambda: proxy.stats().refused == 1)


def test_closing_the_proxy_closes_its_connections(echo: tuple[str, int]) -> None:
    proxy = LinkProxy(echo)
    with proxy:
        connection = _connect(proxy)
        assert _echoes(connection, b"x")
    with connection, pytest.raises(ConnectionResetError):
        connection.recv(65536)
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(proxy.address, timeout=5.0)
    with pytest.raises(LinkProxyError, match="not started"):
        proxy.cut()


@pytest.mark.parametrize(
    ("endpoint", "target"),
    [
        ("tcp/127.0.0.1:7447", ("127.0.0.1", 7447)),
        ("tcp/[::1]:80", ("::1", 80)),
        ("tls/127.0.0.1:7447", ("127.0.0.1", 7447)),
    ],
)
def test_a_proxy_fronts_a_zenoh_tcp_endpoint(endpoint: str, target: tuple[str, int]) -> None:
    proxy = LinkProxy.to_endpoint(endpoint)
    assert proxy.target == target
    assert proxy.scheme == endpoint.split("/")[0]  # a TLS link passes through as bytes


@pytest.mark.parametrize("endpoint", ["udp/127.0.0.1:7447", "tcp/127.0.0.1", "127.0.0.1:7447"])
def test_other_endpoints_are_refused(endpoint: str) -> None:
    with pytest.raises(ValueError, match="not a tcp/ or tls/HOST:PORT endpoint"):
        LinkProxy.to_endpoint(endpoint)


@pytest.mark.e2e
@pytest.mark.parametrize("mode", ["silent", "reset"])
def test_zenoh_sessions_lose_each_other_and_meet_again(mode: LinkMode) -> None:
    """As in ``ato run``: the trackside listens, the onboard connects through the proxy; each cut
    and restore returns once both sides have seen it by the other's liveliness token."""
    endpoint = loopback_endpoint()
    listen = ZenohSettings(mode="peer", connect=(), listen=(endpoint,))
    with open_session(listen) as trackside, LinkProxy.to_endpoint(endpoint) as proxy:
        connect = ZenohSettings(mode="peer", connect=(ZenohLinkFault.connect_endpoint(proxy),))
        with open_session(connect) as onboard:
            tokens = (
                declare_liveliness(trackside, ALIVE_TRACKSIDE.format(instance="ts1")),
                declare_liveliness(onboard, ALIVE_ONBOARD.format(vehicle="URV1")),
            )
            link = ZenohLinkFault(proxy, onboard=onboard, trackside=trackside, vehicle_id="URV1")
            try:
                assert link.restore(timeout_s=5.0)  # up already: both tokens seen
                assert link.cut(mode, timeout_s=5.0)
                assert not link.up
                assert link.connections_dropped == 1
                assert link.restore(timeout_s=5.0)
                assert link.up
            finally:
                link.close()
                for token in tokens:
                    token.undeclare()
