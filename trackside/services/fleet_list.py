"""The fleet's list (``GET /vehicles``) as JSON, built at most every :data:`MAX_AGE_S`.

With a thousand vehicles the list is a megabyte: every vehicle's latest status, holder and
lease, validated and serialised. Built on each request it took most of a request's time and,
under the interpreter's lock, delayed every other request and the status stream (docs/
trackside.md, "Benchmark"). The statuses change at 5 Hz, so a list younger than one report
period is as fresh as the fleet; it is built again at once when a hold is taken or given up
in this process (:func:`trackside.services.holds.changes`). A renewed lease, or a hold changed
through another trackside instance on the same database, shows at the next build.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Container, Iterable
from datetime import datetime
from typing import Any

from pydantic_core import to_json, to_jsonable_python

from trackside.api.schemas import REPORT_ONLY_FIELDS
from trackside.bridge import VehicleSnapshot

__all__ = ["MAX_AGE_S", "FleetListCache", "fleet_data", "fleet_json"]

MAX_AGE_S = 0.2
"""The oldest list served [s]: one status period at 5 Hz."""


def fleet_data(
    snapshots: Iterable[VehicleSnapshot],
    held: dict[str, tuple[str, datetime]],
    simulated: Container[str],
) -> list[dict[str, Any]]:
    """Each vehicle as the fleet's list and stream show it (:class:`VehiclePublic`), as JSON
    data made without building the models: each report dumped without the fields the public
    status leaves out, its age and rate added; ``held`` by vehicle the holder and the end of the
    lease (:func:`trackside.services.holds.holders`), ``simulated`` the vehicles the simulated
    operator answers. A third of the models' time for a thousand vehicles; the same JSON
    (``tests/trackside/test_fleet_list.py`` checks it against the models')."""
    vehicles = []
    for snapshot in snapshots:
        holder, until = held.get(snapshot.id, (None, None))
        report = snapshot.status
        status = None
        if report is not None:
            status = report.model_dump(mode="json", exclude=REPORT_ONLY_FIELDS)
            status["age_s"] = snapshot.status_age_s
            status["rate_ok"] = snapshot.status_rate_ok
        vehicles.append(
            {
                "id": snapshot.id,
                "alive": snapshot.alive,
                "status": status,
                "holder": holder,
                "hold_expires_at": to_jsonable_python(until),
                "simulated_operator": snapshot.id in simulated,
            }
        )
    return vehicles


def fleet_json(
    snapshots: Iterable[VehicleSnapshot],
    held: dict[str, tuple[str, datetime]],
    simulated: Container[str],
) -> bytes:
    """:func:`fleet_data` as JSON, the body of ``GET /vehicles``."""
    return to_json(fleet_data(snapshots, held, simulated))


class FleetListCache:
    """The last list built, its build time and the holds' change count it saw; thread-safe
    (one build at a time: the requests that come meanwhile get that build)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._body = b""
        self._built_s = -float("inf")
        self._changes = -1

    def get(self, changes: int, build: Callable[[], bytes]) -> bytes:
        """The list's JSON: the last one if younger than :data:`MAX_AGE_S` and built after the
        holds' ``changes``-th change, else ``build()``'s."""
        with self._lock:
            now = self._clock()
            if changes != self._changes or now - self._built_s >= MAX_AGE_S:
                self._body = build()
                self._built_s, self._changes = now, changes
            return self._body
