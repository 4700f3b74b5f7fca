"""The sensor-fusion listener and the OBCU on real UDP sockets (seed 002 §4.1.1, the online
configuration; ``ato sfa listen``).

- :class:`ListenerRunner`: the listener process. INPUT datagrams on one socket, OUTPUT datagrams
  to the OBCU from a second socket, whose address is where the OBCU's ACKs come back.
- :class:`ObcuEndpoint`: a :class:`~onboard.sfa.localisation.Localisation` behind a socket:
  OUTPUT datagrams in, ACKs to their source address.
- :func:`parse_address`: ``HOST:PORT`` options.

The interface-modules emulator that feeds a listener from an emulated drive
(``ato sfa emulate``) is a bench: :func:`deploy.bench.sfa_emulator.send_drive`.

Sockets are opened by the constructors (never at import) and read without blocking; the time
comes from the clock passed in (``time.monotonic`` by default), the boundary where wall time
enters.
"""

from __future__ import annotations

import logging
import select
import socket
import threading
import time
from collections.abc import Callable
from types import TracebackType

from onboard.sfa._exceptions import AddressError
from onboard.sfa.listener import ListenerCore
from onboard.sfa.localisation import Localisation

__all__ = ["Address", "Clock", "ListenerRunner", "ObcuEndpoint", "parse_address"]

log = logging.getLogger(__name__)
Address = tuple[str, int]
Clock = Callable[[], float]
RECEIVE_BUFFER_BYTES = 4 * 1024 * 1024
MAX_DATAGRAM_BYTES = 65535


def parse_address(text: str) -> Address:
    """``HOST:PORT`` → (host, port).

    Raises
    ------
    AddressError
        If it does not parse or the port is outside 0..65535.
    """
    host, separator, port_text = text.rpartition(":")
    if not separator or not host:
        raise AddressError(f"{text!r} is not HOST:PORT")
    try:
        port = int(port_text)
    except ValueError as exc:
        raise AddressError(f"{text!r}: port {port_text!r} is not a number") from exc
    if not 0 <= port <= 65535:
        raise AddressError(f"{text!r}: port outside 0..65535")
    return host.strip("[]"), port


def _udp_socket(bind_to: Address) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
        sock.bind(bind_to)
    except OSError:
        sock.close()
        raise
    sock.setblocking(False)
    return sock


def _drain(sock: socket.socket) -> list[tuple[bytes, Address]]:
    received: list[tuple[bytes, Address]] = []
    while True:
        try:
            data, source = sock.recvfrom(MAX_DATAGRAM_BYTES)
        except (BlockingIOError, InterruptedError):
            return received
        except ConnectionError:  # an ICMP error reported on a later read: consumed, go on
            continue
        received.append((data, source))


class ListenerRunner:
    """The listener on sockets: ``run`` until STOP (exit status 0) or ``stop`` is set.

    Parameters
    ----------
    core : ListenerCore
        The decode/filter core.
    input_address : (host, port)
        Where INPUT datagrams arrive (port 0: any free port, see :attr:`input_address`).
    obcu_address : (host, port)
        Where OUTPUT datagrams go.
    clock : callable
        Seconds, monotonic.
    """

    def __init__(
        self,
        core: ListenerCore,
        *,
        input_address: Address,
        obcu_address: Address,
        clock: Clock = time.monotonic,
    ) -> None:
        self.core = core
        self.obcu_address = obcu_address
        self.clock = clock
        self.input_socket = _udp_socket(input_address)
        try:
            self.output_socket = _udp_socket((input_address[0], 0))
        except OSError:
            self.input_socket.close()
            raise
        self.send_errors = 0
        self._link_lost = False

    @property
    def input_address(self) -> Address:
        host, port = self.input_socket.getsockname()[:2]
        return str(host), int(port)

    def __enter__(self) -> ListenerRunner:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        self.input_socket.close()
        self.output_socket.close()

    def _send(self, outputs: list[bytes]) -> None:
        for output in outputs:
            try:
                self.output_socket.sendto(output, self.obcu_address)
            except OSError:
                self.send_errors += 1

    def poll_once(self, timeout_s: float = 0.05) -> None:
        """Wait up to ``timeout_s`` for datagrams, then handle everything that is there."""
        readable, _, _ = select.select([self.input_socket, self.output_socket], [], [], timeout_s)
        core = self.core
        if self.output_socket in readable:
            for data, _ in _drain(self.output_socket):
                core.on_ack(data, self.clock())
        if self.input_socket in readable:
            for data, _ in _drain(self.input_socket):
                self._send(core.feed(data, self.clock()))
        now_s = self.clock()
        self._send(core.poll(now_s))
        lost = core.link_lost(now_s)
        if lost != self._link_lost:
            log.warning("OBCU link %s", "lost: no ACK for 3 s" if lost else "back")
            self._link_lost = lost

    def run(self, stop: threading.Event | None = None) -> int:
        """Serve until a STOP packet (flushed) or ``stop``; returns the exit status, 0."""
        while not self.core.stopped and not (stop is not None and stop.is_set()):
            self.poll_once()
        self._send(self.core.stop())
        return 0


class ObcuEndpoint:
    """A :class:`Localisation` on a socket: OUTPUT in, ACKs back to where OUTPUT came from."""

    def __init__(
        self, localisation: Localisation, address: Address, *, clock: Clock = time.monotonic
    ) -> None:
        self.localisation = localisation
        self.clock = clock
        self.socket = _udp_socket(address)
        self.send_errors = 0
        self._source: Address | None = None

    @property
    def address(self) -> Address:
        host, port = self.socket.getsockname()[:2]
        return str(host), int(port)

    def close(self) -> None:
        self.socket.close()

    def poll(self) -> None:
        """Read what arrived, refresh the estimate and send the ACKs due."""
        for data, source in _drain(self.socket):
            self._source = source
            self.localisation.receive(data, self.clock())
        acks = self.localisation.step(self.clock())
        if self._source is not None:
            for ack in acks:
                try:
                    self.socket.sendto(ack, self._source)
                except OSError:
                    self.send_errors += 1
