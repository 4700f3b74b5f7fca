"""Per-vehicle live feeds for WebSocket clients, with backpressure.

The bridge publishes from Zenoh's threads; a feed only stores and signals, never waits. Status
is latest-wins (a slow browser skips old reports), events queue up to a bound (the oldest is
dropped and counted beyond it). The WebSocket side awaits :meth:`VehicleFeed.wait` on its loop.
"""

from __future__ import annotations

import asyncio
import threading
from collections import deque
from datetime import UTC, datetime
from typing import Any

from protocol import messages as m

__all__ = ["LiveHub", "VehicleFeed", "event_public"]

EVENT_QUEUE = 256


def event_public(event: m.Event, received_at: datetime) -> dict[str, Any]:
    """An event as ``GET /vehicles/{id}/events`` and the WebSocket show it."""
    return {
        "sim_time_s": event.sim_time_s,
        "received_at": received_at.isoformat(),
        "severity": event.severity.value,
        "code": event.code,
        "text": event.text,
        "seq": event.seq,
    }


class VehicleFeed:
    """What one browser has not sent yet: the newest status and the queued events."""

    def __init__(self, loop: asyncio.AbstractEventLoop, max_events: int = EVENT_QUEUE) -> None:
        self._loop = loop
        self._lock = threading.Lock()
        self._status: m.StatusReport | None = None
        self._events: deque[dict[str, Any]] = deque(maxlen=max_events)
        self._ready = asyncio.Event()
        self.dropped_events = 0
        self.skipped_status = 0

    def _signal(self) -> None:
        try:
            self._loop.call_soon_threadsafe(self._ready.set)
        except RuntimeError:  # the loop has closed: the browser is gone
            return

    def push_status(self, report: m.StatusReport) -> None:
        with self._lock:
            if self._status is not None:
                self.skipped_status += 1
            self._status = report
        self._signal()

    def push_event(self, event: dict[str, Any]) -> None:
        with self._lock:
            if len(self._events) == self._events.maxlen:
                self.dropped_events += 1
            self._events.append(event)
        self._signal()

    async def wait(self, timeout_s: float) -> None:
        try:
            await asyncio.wait_for(self._ready.wait(), timeout_s)
        except TimeoutError:
            return
        finally:
            self._ready.clear()

    def take(self) -> tuple[m.StatusReport | None, list[dict[str, Any]]]:
        with self._lock:
            status, self._status = self._status, None
            events = list(self._events)
            self._events.clear()
        return status, events


class LiveHub:
    """Routes each vehicle's status and events to the feeds open on it."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._feeds: dict[str, set[VehicleFeed]] = {}

    def open(self, vehicle_id: str, loop: asyncio.AbstractEventLoop) -> VehicleFeed:
        feed = VehicleFeed(loop)
        with self._lock:
            self._feeds.setdefault(vehicle_id, set()).add(feed)
        return feed

    def close(self, vehicle_id: str, feed: VehicleFeed) -> None:
        with self._lock:
            self._feeds.get(vehicle_id, set()).discard(feed)

    def _of(self, vehicle_id: str) -> list[VehicleFeed]:
        with self._lock:
            return list(self._feeds.get(vehicle_id, ()))

    def publish_status(self, report: m.StatusReport) -> None:
        for feed in self._of(report.vehicle_id):
            feed.push_status(report)

    def publish_event(self, event: m.Event, received_at: datetime | None = None) -> None:
        feeds = self._of(event.vehicle_id)
        if feeds:
            public = event_public(event, received_at or datetime.now(UTC))
            for feed in feeds:
                feed.push_event(public)
