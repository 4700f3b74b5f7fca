"""The onboard Track Database Manager, alone and inside the node over Zenoh."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import zenoh

from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from onboard.track_database_manager import TrackDatabaseManager
from protocol import TypedPublisher, TypedSubscriber
from protocol import messages as m
from protocol.registry import JOURNEY_PROFILE, JOURNEY_PROFILE_ACK
from tests.conftest import wait_for
from trackdb import TrackMap, load_seed_line
from trackside.bridge import ZenohBridge

RING = TrackMap(load_seed_line("bologna-ring"))


def _profile(version: str = RING.version, **overrides: object) -> m.JourneyProfile:
    values: dict[str, object] = {
        "vehicle_id": "URV1",
        "journey_id": "lap",
        "version": 1,
        "status": m.JourneyProfileStatus.VALID,
        "line_id": "bologna-ring",
        "track_data_version": version,
        "timing_points": (
            m.TimingPoint(id="east", position_m=1975.0, kind="stopping", arrival_time_s=300.0),
            m.TimingPoint(
                id="north",
                position_m=550.0,
                kind="stopping",
                arrival_time_s=900.0,
                end_of_journey=True,
            ),
        ),
    }
    return m.JourneyProfile.model_validate(values | overrides)


def _manager(trackside_version: str | None) -> TrackDatabaseManager:
    manager = TrackDatabaseManager(RING)
    manager.record_trackside_version(
        m.LineVersionReply(line_id="bologna-ring", version=trackside_version)
    )
    return manager


def test_accepts_a_journey_on_matching_track_data() -> None:
    manager = _manager(RING.version)
    assert manager.versions_match
    review = manager.review(_profile())
    assert review.accepted
    assert review.reason is None
    assert manager.journey is not None


@pytest.mark.parametrize(
    ("trackside_version", "profile", "reason"),
    [
        (None, _profile(), "not known"),
        ("0" * 64, _profile(), "differ from the trackside"),
        (RING.version, _profile(version="f" * 64), "other track data"),
        (RING.version, _profile(line_id="milano-bologna"), "is for line"),
        (RING.version, _profile(status=m.JourneyProfileStatus.INVALID), "status"),
    ],
)
def test_refuses_with_a_reason(
    trackside_version: str | None, profile: m.JourneyProfile, reason: str
) -> None:
    review = _manager(trackside_version).review(profile)
    assert not review.accepted
    assert review.reason is not None
    assert reason in review.reason


def test_a_reply_about_another_line_is_ignored() -> None:
    manager = TrackDatabaseManager(RING)
    manager.record_trackside_version(
        m.LineVersionReply(line_id="milano-bologna", version=RING.version)
    )
    assert manager.trackside_version is None


def test_localise_wraps_on_the_ring() -> None:
    assert _manager(None).localise(5700.0 + 12.5) == pytest.approx(12.5)


@pytest.fixture
def node_with_trackside(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
) -> Iterator[tuple[OnboardNode, zenoh.Session, ZenohBridge]]:
    """The node beside a trackside's bridge that holds the ring (it answers the track-data query
    and the handshake, and seals what is sent in the session)."""
    trackside, onboard = zenoh_pair
    bridge = ZenohBridge(trackside, instance_id="ts-test", line_version=lambda _line: RING.version)
    node = OnboardNode(
        OnboardSettings(vehicle_id="URV1"), session=onboard, clock=SimClock(), track_map=RING
    )
    yield node, trackside, bridge
    node.close()
    bridge.close()


def test_node_checks_versions_and_acknowledges_journeys(
    node_with_trackside: tuple[OnboardNode, zenoh.Session, ZenohBridge],
) -> None:
    node, trackside, bridge = node_with_trackside

    # The track_data task asks at t = 0; the answer is taken at a later commands tick.
    def versions_checked() -> bool:
        node.run(0.05)
        return node.track_database.versions_match and node.session_client.established

    assert wait_for(versions_checked)
    acks: list[m.JourneyProfileAck] = []
    with (
        TypedSubscriber(trackside, JOURNEY_PROFILE_ACK, on_message=lambda _k, a: acks.append(a)),
        TypedPublisher(trackside, JOURNEY_PROFILE, vehicle="URV1") as journeys,
    ):
        bad = _profile(version="e" * 64, journey_id="stale")

        def stale_journey_answered() -> bool:
            journeys.put(bad.model_copy(update={"freshness": bridge.seal("URV1")}))
            node.run(0.05)
            return bool(acks)

        assert wait_for(stale_journey_answered)
        assert not acks[0].accepted
        assert "other track data" in (acks[0].reason or "")
        journeys.put(_profile().model_copy(update={"freshness": bridge.seal("URV1")}))

        def journey_accepted() -> bool:
            node.run(0.05)
            return any(a.accepted for a in acks)

        assert wait_for(journey_accepted)
    assert node.status(node.clock.now_ns).journey_id == "lap"
