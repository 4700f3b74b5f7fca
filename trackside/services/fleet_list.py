"""The fleet's list (``GET /vehicles``) as JSON, built at most every :data:`MAX_AGE_S`, away
from the requests.

With a thousand vehicles the list is a megabyte: every vehicle's latest status, holder and
lease, validated and serialised. Built on each request it took most of a request's time and,
under the interpreter's lock, delayed every other request and the status stream (docs/
trackside.md, "Benchmark"). The statuses change at 5 Hz, so a list younger than one report
period is as fresh as the fleet; it is built again at once when a hold is taken or given up
in this process (:func:`trackside.services.holds.changes`). A renewed lease, or a hold changed
through another trackside instance on the same database, shows at the next build.

A request that finds the list older than a period gets it all the same and has a new one built
on a thread of its own: no request waits for a build (a thousand vehicles' list took a request
tens of milliseconds under load, and the others waited for it), and a list is at most a period
and a build old. After a quiet spell (a list older than :data:`STALE_LIMIT_S`), or when a hold
has changed, the request builds the list and waits for it.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Container, Iterable
from datetime import datetime

from pydantic_core import to_json

from protocol import messages as m
from trackside.api.schemas import REPORT_ONLY_FIELDS
from trackside.bridge import VehicleSnapshot

__all__ = ["MAX_AGE_S", "STALE_LIMIT_S", "FleetListCache", "fleet_frame", "fleet_json"]

_log = logging.getLogger(__name__)

MAX_AGE_S = 0.2
"""The age [s] from which a list is built again: one status period at 5 Hz."""
STALE_LIMIT_S = 1.0
"""The oldest list served while a new one is built [s]; an older one is built for the request."""


_TRUE_FALSE = (b"false", b"true")


def _status_json(report: m.StatusReport, age_s: float | None, rate_ok: bool) -> bytes:
    """A report as the public status's JSON: serialised in one call without the fields the
    public status leaves out, its age and rate spliced in before the closing brace."""
    body: bytes = report.__pydantic_serializer__.to_json(report, exclude=REPORT_ONLY_FIELDS)
    return b"".join(
        (body[:-1], b',"age_s":', to_json(age_s), b',"rate_ok":', _TRUE_FALSE[rate_ok], b"}")
    )


def fleet_json(
    snapshots: Iterable[VehicleSnapshot],
    held: dict[str, tuple[str, datetime]],
    simulated: Container[str],
) -> bytes:
    """Each vehicle as the fleet's list and stream show it (:class:`VehiclePublic`), the body of
    ``GET /vehicles``, written as JSON vehicle by vehicle without building the models; ``held``
    by vehicle the holder and the end of the lease (:func:`trackside.services.holds.holders`),
    ``simulated`` the vehicles the simulated operator answers. The same JSON as the models'
    (``tests/trackside/test_fleet_list.py``).

    Each report is serialised by its model's serialiser straight to JSON, and the vehicle's
    entry is joined around it: no dictionary per report and no single call over the whole list.
    Serialising a thousand vehicles' data in one call held the interpreter for milliseconds that
    no other thread could interrupt (docs/trackside.md, "Fifth sitting"); between two vehicles
    the builder hands it over as any Python code does."""
    entries = []
    for snapshot in snapshots:
        holder, until = held.get(snapshot.id, (None, None))
        report = snapshot.status
        status = (
            b"null"
            if report is None
            else _status_json(report, snapshot.status_age_s, snapshot.status_rate_ok)
        )
        entries.append(
            b"".join(
                (
                    b'{"id":',
                    to_json(snapshot.id),
                    b',"alive":',
                    _TRUE_FALSE[snapshot.alive],
                    b',"status":',
                    status,
                    b',"holder":',
                    to_json(holder),
                    b',"hold_expires_at":',
                    to_json(until),
                    b',"simulated_operator":',
                    _TRUE_FALSE[snapshot.id in simulated],
                    b"}",
                )
            )
        )
    return b"[" + b",".join(entries) + b"]"


def fleet_frame(
    snapshots: Iterable[VehicleSnapshot],
    held: dict[str, tuple[str, datetime]],
    simulated: Container[str],
) -> str:
    """The fleet stream's frame (``/ws/fleet``): :func:`fleet_json`'s list as ``vehicles``."""
    return '{"type":"fleet","vehicles":' + fleet_json(snapshots, held, simulated).decode() + "}"


class FleetListCache:
    """The last list built, its build time and the holds' change count it saw; thread-safe
    (one build at a time: a request that comes meanwhile gets the last list, or waits for the
    build when it needs a newer one)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._building = threading.Lock()
        self._body = b""
        self._built_s = -float("inf")
        self._changes = -1
        self._refreshing = False
        self.failed_refreshes = 0
        """Builds on the refresh thread that raised (the last list stayed served)."""

    def get(self, changes: int, build: Callable[[], bytes]) -> bytes:
        """The list's JSON: the last one if built after the holds' ``changes``-th change and
        younger than :data:`STALE_LIMIT_S` (with a new one built on a thread when it is older
        than :data:`MAX_AGE_S`), else ``build()``'s. ``build`` must not use the request's
        resources: it may run after the request has ended."""
        with self._lock:
            age_s = self._clock() - self._built_s
            if changes == self._changes and age_s < STALE_LIMIT_S:
                if age_s >= MAX_AGE_S and not self._refreshing:
                    self._refreshing = True
                    threading.Thread(
                        target=self._refresh, args=(changes, build), name="fleet-list", daemon=True
                    ).start()
                return self._body
        return self._build(changes, build)

    def _build(self, changes: int, build: Callable[[], bytes]) -> bytes:
        with self._building:
            with self._lock:  # built while this request waited for the build before
                if changes == self._changes and self._clock() - self._built_s < MAX_AGE_S:
                    return self._body
            started_s = self._clock()
            body = build()
            with self._lock:
                self._body, self._built_s, self._changes = body, started_s, changes
            return body

    def _refresh(self, changes: int, build: Callable[[], bytes]) -> None:
        try:
            self._build(changes, build)
        except Exception:  # the last list stays served; the next request tries again
            self.failed_refreshes += 1
            _log.exception("the fleet's list could not be built again")
        finally:
            with self._lock:
                self._refreshing = False
