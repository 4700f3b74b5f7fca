"""The benchmark's own code keeps working (its timings are printed by ``ato bench``, not tested)."""

from __future__ import annotations

import zenoh

from deploy.bench.zenoh_bench import VEHICLE, measure_round_trips
from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from tests.conftest import wait_for
from trackdb import TrackMap, load_seed_line


def test_measure_round_trips_against_the_real_node(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    trackside, onboard = zenoh_pair
    node = OnboardNode(
        OnboardSettings(vehicle_id=VEHICLE),
        session=onboard,
        clock=SimClock(),
        track_map=TrackMap(load_seed_line("bologna-ring")),
    )
    try:
        assert wait_for(lambda: _answers(trackside))
        samples = measure_round_trips(trackside, count=50, warmup=5)
    finally:
        node.close()
    assert len(samples) == 50
    assert all(sample > 0 for sample in samples)


def _answers(session: zenoh.Session) -> bool:
    try:
        measure_round_trips(session, count=1, warmup=0)
    except Exception:
        return False
    return True
