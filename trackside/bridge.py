"""The trackside's Zenoh side: which vehicles are alive, and their latest status.

A vehicle is alive while its liveliness token ``ato/alive/ob/{vehicle}`` exists; Zenoh withdraws
the token when the onboard's session closes, or after the link lease (≤ 1 s) when the process
freezes or its link breaks. Vehicles once seen stay listed, as not alive.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import zenoh

from protocol import LivelinessWatcher, TypedQueryable, TypedSubscriber, declare_liveliness
from protocol import messages as m
from protocol.registry import ALIVE_ONBOARD, ALIVE_TRACKSIDE, LINE_VERSION, STATUS

__all__ = ["VehicleSnapshot", "ZenohBridge"]

ChangeListener = Callable[[], None]
LineVersionLookup = Callable[[str], str | None]
"""The current version of a line, ``None`` when the trackside does not hold it."""


@dataclass(frozen=True)
class VehicleSnapshot:
    id: str
    alive: bool
    status: m.StatusReport | None
    status_age_s: float | None
    status_rate_ok: bool


class ZenohBridge:
    """Subscribes to every vehicle's liveliness and status on an open session."""

    def __init__(
        self,
        session: zenoh.Session,
        *,
        instance_id: str,
        line_version: LineVersionLookup | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._known: set[str] = set()
        self._alive: set[str] = set()
        self._listeners: list[ChangeListener] = []
        self._status = TypedSubscriber(session, STATUS, on_message=self._on_status, clock=clock)
        self._liveliness = LivelinessWatcher(
            session, ALIVE_ONBOARD.format(vehicle="*"), self._on_liveliness
        )
        self._line_version = line_version
        self._line_versions = TypedQueryable(session, LINE_VERSION, self._answer_line_version)
        self._token = declare_liveliness(session, ALIVE_TRACKSIDE.format(instance=instance_id))

    def _answer_line_version(
        self, chunks: dict[str, str], request: m.LineVersionRequest
    ) -> m.LineVersionReply:
        if request.line_id != chunks["line"]:
            raise ValueError(f"request for {request.line_id} sent on {chunks['line']}'s key")
        version = None if self._line_version is None else self._line_version(request.line_id)
        return m.LineVersionReply(line_id=request.line_id, version=version)

    @property
    def status_stats(self) -> object:
        return self._status.stats

    def add_listener(self, listener: ChangeListener) -> None:
        with self._lock:
            self._listeners.append(listener)

    def remove_listener(self, listener: ChangeListener) -> None:
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)

    def _notify(self) -> None:
        with self._lock:
            listeners = list(self._listeners)
        for listener in listeners:
            listener()

    def _on_liveliness(self, key: str, alive: bool) -> None:
        vehicle = key.rsplit("/", 1)[-1]
        with self._lock:
            self._known.add(vehicle)
            if alive:
                self._alive.add(vehicle)
            else:
                self._alive.discard(vehicle)
        if not alive:
            self._status.forget(STATUS.key(vehicle=vehicle))
        self._notify()

    def _on_status(self, key: str, report: m.StatusReport) -> None:
        del key, report
        self._notify()

    def vehicle_ids(self) -> list[str]:
        with self._lock:
            return sorted(self._known)

    def snapshot(self, vehicle_id: str) -> VehicleSnapshot | None:
        with self._lock:
            if vehicle_id not in self._known:
                return None
            alive = vehicle_id in self._alive
        key = STATUS.key(vehicle=vehicle_id)
        status = self._status.latest(key) if alive else None
        if status is not None and status.vehicle_id != vehicle_id:
            status = None  # published under another vehicle's key: not trusted
        last = self._status.monitor.last_seen(key)
        age = None if last is None or status is None else self._clock() - last
        return VehicleSnapshot(
            id=vehicle_id,
            alive=alive,
            status=status,
            status_age_s=age,
            status_rate_ok=alive and self._status.monitor.rate_ok(key),
        )

    def fleet(self) -> list[VehicleSnapshot]:
        snapshots = (self.snapshot(vehicle) for vehicle in self.vehicle_ids())
        return [snapshot for snapshot in snapshots if snapshot is not None]

    def close(self) -> None:
        self._token.undeclare()
        self._line_versions.close()
        self._liveliness.close()
        self._status.close()
