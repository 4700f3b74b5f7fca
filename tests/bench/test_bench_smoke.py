"""The benchmark's own code keeps working (its timings are printed by ``ato bench``, not tested)."""

from __future__ import annotations

import zenoh

from deploy.bench.zenoh_bench import (
    VEHICLE,
    measure_round_trips,
    open_vehicle_session,
    trackside_bridge,
)
from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from trackdb import TrackMap, load_seed_line


def test_measure_round_trips_against_the_real_node(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> None:
    """The pings go through a trackside's bridge, sealed for the node's session, and are
    accepted (a bare ping would be refused, and the bench would raise)."""
    trackside, onboard = zenoh_pair
    bridge = trackside_bridge(trackside)
    node = OnboardNode(
        OnboardSettings(vehicle_id=VEHICLE),
        session=onboard,
        clock=SimClock(),
        track_map=TrackMap(load_seed_line("bologna-ring")),
    )
    try:
        open_vehicle_session(bridge, 10.0, node=node)
        samples = measure_round_trips(bridge, count=50, warmup=5)
    finally:
        node.close()
        bridge.close()
    assert len(samples) == 50
    assert all(sample > 0 for sample in samples)
