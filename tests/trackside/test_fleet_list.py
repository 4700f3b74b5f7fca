"""The fleet's list as JSON, built at most once a status period and again at once when a hold
changes (``trackside.services.fleet_list``)."""

from __future__ import annotations

import gc
import json
import sys
import time
from collections.abc import Callable
from datetime import UTC, datetime

import pytest
from fastapi.testclient import TestClient
from hypothesis import given
from hypothesis import strategies as st
from pydantic import TypeAdapter

from protocol import messages as m
from tests.protocol.strategies import status_reports
from trackside.api.schemas import VehiclePublic
from trackside.bridge import VehicleSnapshot
from trackside.main import GC_THRESHOLDS, SWITCH_INTERVAL_S
from trackside.services.fleet_list import (
    MAX_AGE_S,
    STALE_LIMIT_S,
    FleetListCache,
    fleet_frame,
    fleet_json,
)

_LIST = TypeAdapter(list[VehiclePublic])


class Clock:
    def __init__(self) -> None:
        self.now_s = 100.0

    def __call__(self) -> float:
        return self.now_s


def _builder(builds: list[str]) -> Callable[[], bytes]:
    """A list of one vehicle whose holder names the build: driver1, driver2…"""

    def build() -> bytes:
        builds.append("URV1")
        vehicle = VehiclePublic(id="URV1", alive=True, status=None, holder=f"driver{len(builds)}")
        return _LIST.dump_json([vehicle])

    return build


def _holder(body: bytes) -> str:
    return str(json.loads(body)[0]["holder"])


def _wait_for(builds: list[str], count: int) -> None:
    deadline = time.monotonic() + 10.0
    while len(builds) < count and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.05)  # the refresh stores its list after its build returns


def test_the_list_is_kept_one_period_and_built_again_when_a_hold_changes() -> None:
    clock = Clock()
    cache = FleetListCache(clock)
    builds: list[str] = []
    build = _builder(builds)

    assert _holder(cache.get(0, build)) == "driver1"
    clock.now_s += MAX_AGE_S / 2
    assert _holder(cache.get(0, build)) == "driver1"  # kept
    assert _holder(cache.get(1, build)) == "driver2"  # a hold changed: built for the request
    assert len(builds) == 2


def test_an_old_list_is_served_while_a_new_one_is_built_away_from_the_request() -> None:
    clock = Clock()
    cache = FleetListCache(clock)
    builds: list[str] = []
    build = _builder(builds)
    cache.get(0, build)
    clock.now_s += MAX_AGE_S
    assert _holder(cache.get(0, build)) == "driver1"  # served at once, a build started
    _wait_for(builds, 2)
    assert _holder(cache.get(0, build)) == "driver2"
    clock.now_s += STALE_LIMIT_S  # a quiet spell: too old to serve, built for the request
    assert _holder(cache.get(0, build)) == "driver3"
    assert len(builds) == 3


def test_a_failed_build_away_from_the_request_leaves_the_last_list_served() -> None:
    clock = Clock()
    cache = FleetListCache(clock)
    builds: list[str] = []
    cache.get(0, _builder(builds))
    clock.now_s += MAX_AGE_S

    def broken() -> bytes:
        builds.append("broken")
        raise RuntimeError("database gone")

    assert _holder(cache.get(0, broken)) == "driver1"
    _wait_for(builds, 2)
    assert cache.failed_refreshes == 1
    assert _holder(cache.get(0, _builder(builds))) == "driver1"  # served, and tried again
    _wait_for(builds, 3)
    assert _holder(cache.get(0, _builder(builds))) == "driver3"


@given(
    reports=st.lists(st.none() | status_reports, min_size=1, max_size=4),
    age_s=st.none() | st.floats(0.0, 10.0),
    held=st.booleans(),
)
def test_the_list_s_json_is_the_public_models_json(
    reports: list[m.StatusReport | None], age_s: float | None, held: bool
) -> None:
    """The list and the stream's frame are made as JSON data straight from the reports (a third
    of the time for a thousand vehicles): the same JSON as the public models', every report
    field included."""
    snapshots = [
        VehicleSnapshot(
            id=f"V{index}",
            alive=report is not None,
            status=report,
            status_age_s=None if report is None else age_s,
            status_rate_ok=index % 2 == 0,
        )
        for index, report in enumerate(reports)
    ]
    until = datetime(2026, 12, 7, 5, 0, 0, 123456, tzinfo=UTC)
    holders = {"V0": ("driver", until)} if held else {}
    simulated = {"V1"}
    models = [
        VehiclePublic.from_snapshot(
            snapshot,
            holder=holders.get(snapshot.id, (None, None))[0],
            hold_expires_at=holders.get(snapshot.id, (None, None))[1],
            simulated_operator=snapshot.id in simulated,
        )
        for snapshot in snapshots
    ]
    expected = json.loads(_LIST.dump_json(models))
    assert json.loads(fleet_json(snapshots, holders, simulated)) == expected
    # The fleet stream's frame, sent as JSON text, carries the same data.
    frame = json.loads(fleet_frame(snapshots, holders, simulated))
    assert frame == {"type": "fleet", "vehicles": expected}


def test_the_service_hands_the_interpreter_over_every_half_millisecond(client: TestClient) -> None:
    """A request waits for the interpreter at each database call while the status reports are
    validated: the service shortens the switch interval from Python's 5 ms while it runs."""
    assert client.get("/healthz").status_code == 200
    assert sys.getswitchinterval() == pytest.approx(SWITCH_INTERVAL_S)


def test_the_service_collects_its_young_objects_less_often_while_it_runs(
    client: TestClient,
) -> None:
    """Each young collection stops every thread: the service makes them rarer while it runs."""
    assert client.get("/healthz").status_code == 200
    assert gc.get_threshold() == GC_THRESHOLDS
    assert GC_THRESHOLDS[0] > 700  # Python's default
