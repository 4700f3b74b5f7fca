"""A TCP link that can be cut: the ``zenoh_link_loss`` fault between two Zenoh sessions.

:class:`LinkProxy` listens on a loopback port and forwards every connection it accepts to a target
(in ``ato run``, the trackside's Zenoh endpoint; the onboard's session connects to the proxy
instead). While the link is cut nothing crosses it:

- ``silent`` (a radio link gone quiet, the default): established connections stall; what is sent
  waits in the sockets' buffers, as TCP holds unacknowledged segments, so each side notices the
  loss only by its own link lease. A connection opened meanwhile is accepted and never answered
  (a black hole).
- ``reset``: established connections are reset at once (TCP RST) and new ones are refused
  (accepted and reset).

Restoring the link resets the black-holed connections (their openers have given up on them) and
lets the stalled ones go on; the sessions' own connect retries rebuild whatever was closed.

The forwarding runs in a child process (``python -m deploy.link_proxy``), not on a thread of the
caller's: in a simulation's process a planner running in C can hold the interpreter lock for
longer than Zenoh's link lease (1 s), and a forwarding thread held off that long breaks the link
with no fault injected. :class:`LinkProxy` starts and stops the child with
:class:`deploy.processes.ChildProcess` and drives it over its standard input and output, one JSON
line per request and per answer (the first answer says it listens); :meth:`LinkProxy.cut` and
:meth:`LinkProxy.restore` return once done. The proxy knows nothing of simulated time: the
scenario runner decides when to cut and to restore (``deploy.scenario.zenoh_link``). The child
runs this module on the standard library alone, so that it starts in a moment.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import signal
import socket
import struct
import sys
import threading
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import IO, TYPE_CHECKING, Any, Literal, Self

from deploy._exceptions import DeployError

if TYPE_CHECKING:
    # Imported where the parent starts the child: the child itself runs on the standard library.
    from deploy.processes import ChildProcess

__all__ = ["LinkMode", "LinkProxy", "LinkProxyError", "LinkStats", "main"]

LinkMode = Literal["silent", "reset"]
CHUNK_BYTES = 65536
START_TIMEOUT_S = 10.0
"""How long the child may take to start listening [s]."""
ANSWER_TIMEOUT_S = 5.0
"""How long the child may take to answer a request [s]."""


class LinkProxyError(DeployError, OSError):
    """The proxy could not start, or did not answer in time."""


@dataclass(frozen=True)
class LinkStats:
    """What the proxy has seen since it started."""

    accepted: int = 0
    """Connections accepted from the connecting side."""
    forwarded: int = 0
    """... of which connected through to the target."""
    dropped: int = 0
    """Established connections stalled or reset by a cut."""
    refused: int = 0
    """Connections black-holed or refused while the link was cut, or that the target refused."""
    bytes_up: int = 0
    """Forwarded from the connecting side to the target [bytes]."""
    bytes_down: int = 0
    """Forwarded from the target to the connecting side [bytes]."""
    cuts: int = 0
    open_connections: int = 0
    """Forwarded connections open now, stalled ones included."""


class LinkProxy:
    """A TCP forwarder from ``host:port`` to ``target`` whose link can be cut and restored."""

    def __init__(
        self,
        target: tuple[str, int],
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        scheme: str = "tcp",
    ) -> None:
        self.target = target
        self.scheme = scheme
        """The Zenoh link's scheme: ``tls`` links pass through as bytes, as ``tcp`` ones."""
        self._bind = (host, port)
        self._address: tuple[str, int] | None = None
        self._child: ChildProcess | None = None
        self._lock = threading.Lock()
        self._up = True

    @classmethod
    def to_endpoint(cls, endpoint: str) -> LinkProxy:
        """A proxy in front of a Zenoh TCP or TLS endpoint such as ``tls/127.0.0.1:7447``."""
        protocol, _, address = endpoint.partition("/")
        host, _, port = address.rpartition(":")
        if protocol not in ("tcp", "tls") or not host or not port.isdigit():
            raise ValueError(f"not a tcp/ or tls/HOST:PORT endpoint: {endpoint!r}")
        return cls((host.removeprefix("[").removesuffix("]"), int(port)), scheme=protocol)

    # -- life cycle ----------------------------------------------------------------------------

    def start(self) -> None:
        """Start the child process; return once it listens."""
        if self._child is not None:
            return
        from deploy.processes import ChildProcess

        host, port = self._bind
        command = [
            sys.executable,
            "-m",
            "deploy.link_proxy",
            self.target[0],
            str(self.target[1]),
            "--host",
            host,
            "--port",
            str(port),
        ]
        self._child = ChildProcess(
            command,
            name="link proxy",
            control=True,
            stop_line=json.dumps({"op": "close"}),
            stop_timeout_s=ANSWER_TIMEOUT_S,
        )
        self._child.start()
        try:
            answer = self._read(START_TIMEOUT_S)
        except LinkProxyError:
            self.close()
            raise
        if "error" in answer:
            self.close()
            raise LinkProxyError(f"cannot listen on {host}:{port}: {answer['error']}")
        listening = answer["listening"]
        self._address = (str(listening[0]), int(listening[1]))
        self._up = True

    def close(self) -> None:
        """Stop the child: it closes every connection."""
        child, self._child = self._child, None
        if child is not None:
            child.stop()

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    # -- what callers see ----------------------------------------------------------------------

    @property
    def address(self) -> tuple[str, int]:
        if self._address is None:
            raise LinkProxyError("the proxy is not started")
        return self._address

    @property
    def endpoint(self) -> str:
        """The Zenoh endpoint to connect to instead of the target's."""
        host, port = self.address
        return f"{self.scheme}/{host}:{port}"

    @property
    def up(self) -> bool:
        return self._up

    def stats(self) -> LinkStats:
        return LinkStats(**self._request("stats"))

    def cut(self, mode: LinkMode = "silent") -> int:
        """Cut the link; the number of established connections it dropped."""
        dropped = int(self._request("cut", mode=mode)["dropped"])
        self._up = False
        return dropped

    def restore(self) -> None:
        """Let traffic through again."""
        self._request("restore")
        self._up = True

    def _request(self, op: str, **fields: Any) -> dict[str, Any]:
        with self._lock:
            child = self._child
            if child is None:
                raise LinkProxyError("the proxy is not started")
            try:
                child.send_line(json.dumps({"op": op, **fields}))
            except (OSError, ValueError) as exc:
                raise LinkProxyError(f"the proxy is gone: {exc}") from exc
            return self._read(ANSWER_TIMEOUT_S)

    def _read(self, timeout_s: float) -> dict[str, Any]:
        child = self._child
        line = None if child is None else child.read_line(timeout_s)
        if not line:
            raise LinkProxyError(f"the proxy did not answer within {timeout_s} s")
        answer: dict[str, Any] = json.loads(line)
        return answer


# -- the child process -------------------------------------------------------------------------


@dataclass(eq=False)
class _Pipe:
    """One forwarded connection: the accepted side and the target side."""

    client: asyncio.StreamWriter
    target: asyncio.StreamWriter
    tasks: list[asyncio.Task[None]] = field(default_factory=list)


def _reset(writer: asyncio.StreamWriter) -> None:
    """Close with a TCP RST rather than a FIN, as a broken link's peer sees it."""
    sock = writer.get_extra_info("socket")
    if sock is not None:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    writer.transport.abort()


class _Forwarder:
    """The forwarding itself, on the child's event loop."""

    def __init__(self, target: tuple[str, int]) -> None:
        self.target = target
        self._server: asyncio.Server | None = None
        self._resumed = asyncio.Event()
        self._resumed.set()
        self._mode: LinkMode = "silent"
        self._pipes: set[_Pipe] = set()
        self._held: set[asyncio.StreamWriter] = set()
        self.stats = dict.fromkeys(asdict(LinkStats()), 0)

    async def listen(self, host: str, port: int) -> tuple[str, int]:
        self._server = await asyncio.start_server(self._on_client, host, port)
        bound = self._server.sockets[0].getsockname()
        return str(bound[0]), int(bound[1])

    def snapshot(self) -> dict[str, int]:
        return self.stats | {"open_connections": len(self._pipes)}

    async def shut(self) -> None:
        if self._server is not None:
            self._server.close()
        tasks = [task for pipe in self._pipes for task in pipe.tasks]
        for pipe in list(self._pipes):
            self._end(pipe, reset=True)
        for writer in self._held:
            _reset(writer)
        self._held.clear()
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

    def cut(self, mode: LinkMode) -> int:
        self._mode = mode
        self._resumed.clear()
        self.stats["cuts"] += 1
        dropped = len(self._pipes)
        self.stats["dropped"] += dropped
        if mode == "reset":
            for pipe in list(self._pipes):
                self._end(pipe, reset=True)
        return dropped

    def restore(self) -> None:
        for writer in self._held:
            _reset(writer)
        self._held.clear()
        self._resumed.set()

    def _refuse(self, writer: asyncio.StreamWriter) -> None:
        self.stats["refused"] += 1
        if self._mode == "reset":
            _reset(writer)
        else:
            self._held.add(writer)

    async def _on_client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.stats["accepted"] += 1
        if not self._resumed.is_set():
            self._refuse(writer)
            return
        try:
            target_reader, target_writer = await asyncio.open_connection(*self.target)
        except OSError:
            self.stats["refused"] += 1
            _reset(writer)
            return
        if not self._resumed.is_set():  # cut while connecting
            _reset(target_writer)
            self._refuse(writer)
            return
        self.stats["forwarded"] += 1
        pipe = _Pipe(writer, target_writer)
        self._pipes.add(pipe)
        pipe.tasks = [
            asyncio.create_task(self._pump(pipe, reader, target_writer, "bytes_up")),
            asyncio.create_task(self._pump(pipe, target_reader, writer, "bytes_down")),
        ]

    async def _pump(
        self,
        pipe: _Pipe,
        reader: asyncio.StreamReader,
        writer: asyncio.StreamWriter,
        counter: str,
    ) -> None:
        """Copy one direction while the link is up; hold (read nothing, write nothing) while it
        is cut; end the pipe when either side closes."""
        try:
            while True:
                await self._resumed.wait()
                data = await reader.read(CHUNK_BYTES)
                if not data:
                    break
                await self._resumed.wait()
                if pipe not in self._pipes:
                    break
                writer.write(data)
                await writer.drain()
                self.stats[counter] += len(data)
        except OSError:
            pass
        finally:
            self._end(pipe, reset=False)

    def _end(self, pipe: _Pipe, *, reset: bool) -> None:
        if pipe not in self._pipes:
            return
        self._pipes.discard(pipe)
        for writer in (pipe.client, pipe.target):
            if reset:
                _reset(writer)
            else:
                writer.close()


def _answer(out: IO[str], answer: dict[str, Any]) -> None:
    out.write(json.dumps(answer) + "\n")
    out.flush()


async def _serve(target: tuple[str, int], host: str, port: int) -> None:
    """Forward, and answer the requests read from standard input until ``close`` or its end."""
    forwarder = _Forwarder(target)
    try:
        address = await forwarder.listen(host, port)
    except OSError as exc:
        _answer(sys.stdout, {"error": str(exc)})
        return
    _answer(sys.stdout, {"listening": list(address)})
    loop = asyncio.get_running_loop()
    requests = asyncio.StreamReader()
    await loop.connect_read_pipe(lambda: asyncio.StreamReaderProtocol(requests), sys.stdin)
    try:
        while line := await requests.readline():
            request = json.loads(line)
            op = request["op"]
            if op == "close":
                break
            if op == "cut":
                _answer(sys.stdout, {"dropped": forwarder.cut(request["mode"])})
            elif op == "restore":
                forwarder.restore()
                _answer(sys.stdout, {})
            else:
                _answer(sys.stdout, forwarder.snapshot())
    finally:
        await forwarder.shut()


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m deploy.link_proxy TARGET_HOST TARGET_PORT [--host H] [--port P]``."""
    parser = argparse.ArgumentParser(prog="python -m deploy.link_proxy", description=__doc__)
    parser.add_argument("target_host")
    parser.add_argument("target_port", type=int)
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=0)
    args = parser.parse_args(argv)
    # The parent ends the child (a Ctrl-C reaches the whole process group).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    asyncio.run(_serve((args.target_host, args.target_port), args.host, args.port))
    return 0


if __name__ == "__main__":
    sys.exit(main())
