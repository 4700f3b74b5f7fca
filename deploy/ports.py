"""Free loopback ports for launchers, benchmarks and tests."""

from __future__ import annotations

import socket

__all__ = ["free_tcp_port", "loopback_endpoint"]


def free_tcp_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def loopback_endpoint() -> str:
    """A Zenoh endpoint on a free loopback port."""
    return f"tcp/127.0.0.1:{free_tcp_port()}"
