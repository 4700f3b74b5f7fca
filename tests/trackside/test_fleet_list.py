"""The fleet's list as JSON, built at most once a status period and again at once when a hold
changes (``trackside.services.fleet_list``)."""

from __future__ import annotations

import json

from trackside.api.schemas import VehiclePublic
from trackside.services.fleet_list import MAX_AGE_S, FleetListCache


class Clock:
    def __init__(self) -> None:
        self.now_s = 100.0

    def __call__(self) -> float:
        return self.now_s


def test_the_list_is_kept_one_period_and_built_again_when_a_hold_changes() -> None:
    clock = Clock()
    cache = FleetListCache(clock)
    builds: list[str] = []

    def build() -> list[VehiclePublic]:
        builds.append("URV1")
        return [VehiclePublic(id="URV1", alive=True, status=None, holder=f"driver{len(builds)}")]

    first = json.loads(cache.get(0, build))
    assert first[0]["holder"] == "driver1"
    clock.now_s += MAX_AGE_S / 2
    assert json.loads(cache.get(0, build)) == first  # kept
    assert json.loads(cache.get(1, build))[0]["holder"] == "driver2"  # a hold changed
    clock.now_s += MAX_AGE_S
    assert json.loads(cache.get(1, build))[0]["holder"] == "driver3"  # a period old
    assert len(builds) == 3
