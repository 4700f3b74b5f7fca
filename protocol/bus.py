"""Typed publish/subscribe, query/reply and liveliness on top of zenoh-python.

Each helper is bound to a :class:`~protocol.registry.Topic`, so it encodes and decodes with the
topic's model and follows its delivery; the query helpers to a
:class:`~protocol.registry.QueryTopic`, so that a reply has its model's type. A receiver never
raises on bad input: it counts the payload in :class:`TopicStats`, logs it and drops it.
:class:`TopicMonitor` derives per-key ``alive`` and ``rate_ok`` from the topic's expected rate
(openpilot's ``SubMaster`` idea).

Zenoh calls the receive callbacks on its own threads; the shared state here is guarded by a lock
and exposed through copies.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, Self, TypeVar

import zenoh

from protocol._exceptions import (
    PayloadError,
    ProtocolError,
    RequestTimeoutError,
    TransportError,
)
from protocol.registry import Delivery, QueryTopic, Topic

__all__ = [
    "LivelinessWatcher",
    "TopicMonitor",
    "TopicStats",
    "TypedPublisher",
    "TypedQueryable",
    "TypedSubscriber",
    "declare_liveliness",
    "request",
    "request_async",
]

T = TypeVar("T")
Request = TypeVar("Request")
Reply = TypeVar("Reply")
TimeSource = Callable[[], float]

_log = logging.getLogger(__name__)

ALIVE_PERIODS = 2.5
"""A key is alive while its last message is younger than this many expected periods."""
RATE_TOLERANCE = 0.2
"""``rate_ok`` holds while the measured rate is within ±20 % of the expected one."""
RATE_WINDOW_S = 5.0


@dataclass
class TopicStats:
    """Counters of one receiver."""

    received: int = 0
    bad_payloads: int = 0
    queue_overflows: int = 0
    last_error: str | None = None


class TopicMonitor:
    """Per-key liveness and rate, from arrival times and the topic's expected rate."""

    def __init__(self, rate_hz: float | None, clock: TimeSource = time.monotonic) -> None:
        self._rate_hz = rate_hz
        self._clock = clock
        self._arrivals: dict[str, deque[float]] = {}
        self._lock = threading.Lock()

    def record(self, key: str, at: float | None = None) -> None:
        stamp = self._clock() if at is None else at
        with self._lock:
            arrivals = self._arrivals.setdefault(key, deque())
            arrivals.append(stamp)
            while arrivals and stamp - arrivals[0] > RATE_WINDOW_S:
                arrivals.popleft()

    def forget(self, key: str) -> None:
        with self._lock:
            self._arrivals.pop(key, None)

    def keys(self) -> list[str]:
        with self._lock:
            return list(self._arrivals)

    def last_seen(self, key: str) -> float | None:
        with self._lock:
            arrivals = self._arrivals.get(key)
            return arrivals[-1] if arrivals else None

    def alive(self, key: str, now: float | None = None) -> bool:
        last = self.last_seen(key)
        if last is None:
            return False
        if self._rate_hz is None:
            return True
        current = self._clock() if now is None else now
        return current - last <= ALIVE_PERIODS / self._rate_hz

    def rate_hz(self, key: str, now: float | None = None) -> float:
        """Measured rate [Hz] over the last window; 0 with fewer than two arrivals."""
        current = self._clock() if now is None else now
        with self._lock:
            return _rate_hz(self._arrivals.get(key) or deque(), current)

    def rate_ok(self, key: str, now: float | None = None) -> bool:
        if not self.alive(key, now):
            return False
        if self._rate_hz is None:
            return True
        measured = self.rate_hz(key, now)
        return abs(measured - self._rate_hz) <= RATE_TOLERANCE * self._rate_hz

    def health(self, now: float | None = None) -> dict[str, tuple[float, bool]]:
        """Every key's last arrival and :meth:`rate_ok`, at one instant and under one lock:
        what a list of a thousand keys asks, without a thousand rounds of the lock."""
        current = self._clock() if now is None else now
        with self._lock:
            return {
                key: (arrivals[-1], self._ok(arrivals, current))
                for key, arrivals in self._arrivals.items()
                if arrivals
            }

    def _ok(self, arrivals: deque[float], current: float) -> bool:
        """:meth:`rate_ok` of a key's (non-empty) arrivals, the lock held."""
        if self._rate_hz is None:
            return True
        if current - arrivals[-1] > ALIVE_PERIODS / self._rate_hz:
            return False
        measured = _rate_hz(arrivals, current)
        return abs(measured - self._rate_hz) <= RATE_TOLERANCE * self._rate_hz


def _rate_hz(arrivals: deque[float], current: float) -> float:
    """The rate [Hz] of ``arrivals`` over the window before ``current``; 0 with fewer than two.

    In the clock's order, and :meth:`TopicMonitor.record` keeps no more than a window behind
    the last: the few older than the window are the first ones."""
    stale = 0
    for stamp in arrivals:
        if current - stamp <= RATE_WINDOW_S:
            break
        stale += 1
    count = len(arrivals) - stale
    if count < 2:
        return 0.0
    span = arrivals[-1] - arrivals[stale]
    return (count - 1) / span if span > 0 else 0.0


class TypedPublisher(Generic[T]):
    """Publishes one topic's messages on one concrete key."""

    def __init__(
        self, session: zenoh.Session, topic: Topic[T], *, block: bool = False, **chunks: str
    ) -> None:
        """``block``: wait for room in the transmission queue even on a ``LATEST`` topic (which
        otherwise drops under congestion), for a publisher that paces itself on the answers."""
        if topic.delivery is Delivery.QUERY:
            raise ProtocolError(f"{topic.name} is a query topic; use request()")
        self.topic = topic
        self.key = topic.key(**chunks)
        latest = topic.delivery is Delivery.LATEST and not block
        try:
            self._publisher = session.declare_publisher(
                self.key,
                congestion_control=(
                    zenoh.CongestionControl.DROP if latest else zenoh.CongestionControl.BLOCK
                ),
                reliability=zenoh.Reliability.RELIABLE,
                # Not express: express messages each take a whole batch of the transmission
                # queue, so a lockstep burst of a few reports overflows it and DROP loses them.
                express=False,
            )
        except zenoh.ZError as exc:
            raise TransportError(f"cannot declare publisher {self.key}: {exc}") from exc
        # A put on Zenoh's callback thread and a close on another must not meet inside the
        # binding: the one that finds the publisher in use fails with "Already borrowed".
        self._lock = threading.Lock()
        self._closed = False

    def put(self, message: T) -> None:
        payload = self.topic.encode(message)
        with self._lock:
            if self._closed:
                raise TransportError(f"put on {self.key} failed: the publisher is closed")
            try:
                self._publisher.put(payload)
            except zenoh.ZError as exc:
                raise TransportError(f"put on {self.key} failed: {exc}") from exc

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._publisher.undeclare()
            except zenoh.ZError:
                _log.debug("publisher %s already gone", self.key)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()


class TypedSubscriber(Generic[T]):
    """Receives one topic, validating every payload.

    ``LATEST`` topics keep the newest message per key; ``FIFO`` topics queue up to ``max_queue``
    messages (the oldest is dropped and counted beyond that). ``on_message`` is called on Zenoh's
    thread after validation, for callers that want a push.

    With ``drain_period_s`` the samples wait in Zenoh's own ring buffer (``ring_capacity``
    samples, filled without the interpreter) and a thread of this subscriber takes them in
    batches: the first at once, those that came meanwhile together, then at most one batch a
    period. A receiver of thousands of samples a second (the trackside's status intake) then
    takes the interpreter a few hundred times a second, not once per sample; a sample waits at
    most a period. A batch that fills the ring may have lost the oldest: counted in
    ``queue_overflows``.
    """

    def __init__(
        self,
        session: zenoh.Session,
        topic: Topic[T],
        *,
        on_message: Callable[[str, T], None] | None = None,
        max_queue: int = 1024,
        clock: TimeSource = time.monotonic,
        drain_period_s: float | None = None,
        ring_capacity: int = 16384,
        **chunks: str,
    ) -> None:
        self.topic = topic
        self.key_expr = topic.wildcard(**chunks)
        self.stats = TopicStats()
        self.monitor = TopicMonitor(topic.rate_hz, clock)
        self._on_message = on_message
        self._latest: dict[str, T] = {}
        self._queue: deque[tuple[str, T]] = deque(maxlen=max_queue)
        self._lock = threading.Lock()
        self._drainer: threading.Thread | None = None
        self._subscriber: zenoh.Subscriber[Any]
        try:
            if drain_period_s is None:
                self._subscriber = session.declare_subscriber(self.key_expr, self._on_sample)
            else:
                ring = session.declare_subscriber(
                    self.key_expr, zenoh.handlers.RingChannel(ring_capacity)
                )
                self._subscriber = ring
                self._drainer = threading.Thread(
                    target=self._drain,
                    args=(ring.handler, drain_period_s, ring_capacity),
                    name=f"{topic.name}-intake",
                    daemon=True,
                )
        except zenoh.ZError as exc:
            raise TransportError(f"cannot subscribe to {self.key_expr}: {exc}") from exc
        if self._drainer is not None:
            self._drainer.start()

    def _drain(self, ring: zenoh.Handler[zenoh.Sample], period_s: float, capacity: int) -> None:
        """Take the ring's samples in batches until the subscriber is undeclared."""
        while True:
            try:
                batch = [ring.recv()]  # waits without the interpreter
                while len(batch) < capacity and (sample := ring.try_recv()) is not None:
                    batch.append(sample)
            except zenoh.ZError:
                return  # undeclared: the ring is closed
            if len(batch) >= capacity:
                with self._lock:
                    self.stats.queue_overflows += 1
            for sample in batch:
                try:
                    self._on_sample(sample)
                except Exception:  # as on Zenoh's thread: one bad sample must not stop intake
                    _log.exception("intake of %s failed", self.key_expr)
            time.sleep(period_s)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        key = str(sample.key_expr)
        try:
            message = self.topic.decode(sample.payload.to_bytes())
        except PayloadError as exc:
            with self._lock:
                self.stats.bad_payloads += 1
                self.stats.last_error = str(exc)[:500]
            _log.warning("dropped bad %s payload on %s: %s", self.topic.name, key, exc)
            return
        self.monitor.record(key)
        with self._lock:
            self.stats.received += 1
            self._latest[key] = message
            if self.topic.delivery is Delivery.FIFO:
                if len(self._queue) == self._queue.maxlen:
                    self.stats.queue_overflows += 1
                self._queue.append((key, message))
        if self._on_message is not None:
            try:
                self._on_message(key, message)
            except Exception:  # a consumer's bug must not kill Zenoh's thread
                _log.exception("on_message callback for %s failed", key)

    def latest(self, key: str) -> T | None:
        with self._lock:
            return self._latest.get(key)

    def latest_all(self) -> dict[str, T]:
        with self._lock:
            return dict(self._latest)

    def forget(self, key: str) -> None:
        with self._lock:
            self._latest.pop(key, None)
        self.monitor.forget(key)

    def try_recv(self) -> tuple[str, T] | None:
        with self._lock:
            return self._queue.popleft() if self._queue else None

    def close(self) -> None:
        try:
            self._subscriber.undeclare()
        except zenoh.ZError:
            _log.debug("subscriber %s already gone", self.key_expr)
        drainer = self._drainer
        if drainer is not None and drainer is not threading.current_thread():
            drainer.join(timeout=5.0)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()


class TypedQueryable(Generic[Request]):
    """Answers one query topic with ``handler(chunks, request) -> reply`` on Zenoh's thread.

    A request that fails validation is answered with an error reply and counted; so is a handler
    that raises a :class:`ProtocolError` or ``ValueError``. The class is generic in the request
    alone (``TypedQueryable[m.Command]``): the handler's reply type is tied to the topic's when
    the queryable is built, and nothing afterwards hands a reply out.
    """

    def __init__(
        self,
        session: zenoh.Session,
        topic: QueryTopic[Request, Reply],
        handler: Callable[[dict[str, str], Request], Reply],
        **chunks: str,
    ) -> None:
        if not isinstance(topic, QueryTopic):
            raise ProtocolError(f"{topic.name} is not a query topic")
        self.topic: Topic[Request] = topic

        def answer(parsed: dict[str, str], request: Request) -> bytes:
            return topic.encode_reply(handler(parsed, request))

        self.key_expr = topic.wildcard(**chunks)
        self.stats = TopicStats()
        self._answer = answer
        self._lock = threading.Lock()
        try:
            self._queryable = session.declare_queryable(self.key_expr, self._on_query)
        except zenoh.ZError as exc:
            raise TransportError(f"cannot declare queryable {self.key_expr}: {exc}") from exc

    def _on_query(self, query: zenoh.Query) -> None:
        key = str(query.key_expr)
        try:
            chunks = self.topic.parse(key)
            payload = query.payload
            if payload is None:
                raise PayloadError(f"{self.topic.name}: empty request")
            request_message = self.topic.decode(payload.to_bytes())
            encoded = self._answer(chunks, request_message)
        except (ProtocolError, ValueError) as exc:
            with self._lock:
                self.stats.bad_payloads += 1
                self.stats.last_error = str(exc)[:500]
            _log.warning("rejected %s query on %s: %s", self.topic.name, key, exc)
            query.reply_err(str(exc)[:500].encode())
            return
        except Exception:  # a handler's bug must not kill Zenoh's thread
            _log.exception("%s handler failed on %s", self.topic.name, key)
            query.reply_err(b"internal error")
            return
        with self._lock:
            self.stats.received += 1
        query.reply(key, encoded)

    def close(self) -> None:
        try:
            self._queryable.undeclare()
        except zenoh.ZError:
            _log.debug("queryable %s already gone", self.key_expr)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()


def request(
    session: zenoh.Session,
    topic: QueryTopic[Request, Reply],
    message: Request,
    *,
    timeout_s: float = 2.0,
    **chunks: str,
) -> Reply:
    """Send a query and return the first valid reply decoded with the topic's reply model.

    Raises :class:`RequestTimeoutError` when nobody answers in time, and :class:`PayloadError`
    when the answer is an error reply or does not validate.
    """
    key = topic.key(**chunks)
    try:
        replies = session.get(key, payload=topic.encode(message), timeout=timeout_s)
        for reply in replies:
            if reply.ok is not None:
                return topic.decode_reply(reply.ok.payload.to_bytes())
            if reply.err is not None:
                text = reply.err.payload.to_bytes().decode(errors="replace")
                raise PayloadError(f"{key}: request refused: {text}")
    except zenoh.ZError as exc:
        raise TransportError(f"query on {key} failed: {exc}") from exc
    raise RequestTimeoutError(f"no reply on {key} within {timeout_s} s")


def request_async(
    session: zenoh.Session,
    topic: QueryTopic[Request, Reply],
    message: Request,
    on_reply: Callable[[Reply], None],
    *,
    timeout_s: float = 2.0,
    **chunks: str,
) -> None:
    """Send a query without waiting; ``on_reply`` gets each valid reply on Zenoh's thread.

    Error replies and replies that do not validate are logged and dropped, as receivers do.
    """
    key = topic.key(**chunks)

    def handle(reply: zenoh.Reply) -> None:
        if reply.ok is None:
            _log.warning("%s: error reply to a query", key)
            return
        try:
            decoded = topic.decode_reply(reply.ok.payload.to_bytes())
        except PayloadError as exc:
            _log.warning("%s: bad reply dropped: %s", key, exc)
            return
        try:
            on_reply(decoded)
        except Exception:  # a consumer's bug must not kill Zenoh's thread
            _log.exception("reply callback for %s failed", key)

    try:
        session.get(key, handle, payload=topic.encode(message), timeout=timeout_s)
    except zenoh.ZError as exc:
        raise TransportError(f"query on {key} failed: {exc}") from exc


def declare_liveliness(session: zenoh.Session, key: str) -> zenoh.LivelinessToken:
    """Declare this process's liveliness token (CONTRACT.md §5)."""
    try:
        return session.liveliness().declare_token(key)
    except zenoh.ZError as exc:
        raise TransportError(f"cannot declare liveliness token {key}: {exc}") from exc


class LivelinessWatcher:
    """Tracks which liveliness tokens under a key expression are alive.

    ``on_change(key, alive)`` is called on Zenoh's thread for every appearance and disappearance;
    tokens present before the watcher started are reported too.
    """

    def __init__(
        self,
        session: zenoh.Session,
        key_expr: str,
        on_change: Callable[[str, bool], None] | None = None,
    ) -> None:
        self._alive: set[str] = set()
        self._lock = threading.Lock()
        self._on_change = on_change
        try:
            self._subscriber = session.liveliness().declare_subscriber(
                key_expr, self._on_sample, history=True
            )
        except zenoh.ZError as exc:
            raise TransportError(f"cannot watch liveliness of {key_expr}: {exc}") from exc

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        alive = sample.kind == zenoh.SampleKind.PUT
        with self._lock:
            if alive:
                self._alive.add(key)
            else:
                self._alive.discard(key)
        if self._on_change is not None:
            try:
                self._on_change(key, alive)
            except Exception:  # a consumer's bug must not kill Zenoh's thread
                _log.exception("liveliness callback for %s failed", key)

    def alive(self) -> set[str]:
        with self._lock:
            return set(self._alive)

    def close(self) -> None:
        try:
            self._subscriber.undeclare()
        except zenoh.ZError:
            _log.debug("liveliness subscriber already gone")

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()
