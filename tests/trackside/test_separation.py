"""Moving-block separation (issue 23): each train's EoA ends behind the train ahead."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from protocol import messages as m
from tests.trackside.reports import status_report
from trackside.separation import MovingBlock, TrainExtent, extent_from_report

RING_M = 5700.0
LENGTH_M = 6.0


def report(
    vehicle_id: str, position_m: float, *, confidence_m: float | None = 2.0, line_id: str = "ring"
) -> m.StatusReport:
    return status_report(vehicle_id, position_m, line_id=line_id, confidence_m=confidence_m)


def place(block: MovingBlock, vehicle_id: str, position_m: float, **kwargs: object) -> None:
    block.update(
        extent_from_report(
            report(vehicle_id, position_m, **kwargs),  # type: ignore[arg-type]
            train_length_m=LENGTH_M,
            received_at_s=0.0,
        )
    )


def test_a_report_gives_the_max_safe_front_and_the_min_safe_rear() -> None:
    extent = extent_from_report(report("URV1", 100.0), train_length_m=6.0, received_at_s=3.0)
    assert (extent.front_m, extent.rear_m, extent.reported_at_s) == (102.0, 92.0, 3.0)
    exact = extent_from_report(
        report("URV1", 100.0, confidence_m=None), train_length_m=6.0, received_at_s=0.0
    )
    assert (exact.front_m, exact.rear_m) == (100.0, 94.0)
    with pytest.raises(ValueError, match="train length"):
        extent_from_report(report("URV1", 100.0), train_length_m=0.0, received_at_s=0.0)


def test_the_eoa_ends_the_margin_behind_the_rear_of_the_train_ahead() -> None:
    block = MovingBlock(margin_m=50.0)
    place(block, "URV1", 100.0)
    place(block, "URV2", 600.0)
    # URV2's min safe rear end: 600 − 2 − 6 = 592; URV1's max safe front end: 102.
    assert block.gap_m("URV1") == pytest.approx(490.0)
    assert block.limit_m("URV1") == pytest.approx(542.0)
    ahead = block.train_ahead("URV1")
    assert ahead is not None
    assert ahead.vehicle_id == "URV2"
    # Nothing ahead of the leader on an open line; an unknown train has no limit.
    assert block.limit_m("URV2") == math.inf
    assert block.limit_m("URV9") is None
    # The leader moves on: the follower's limit moves with it.
    place(block, "URV2", 900.0)
    assert block.limit_m("URV1") == pytest.approx(842.0)
    # Off the line, it bounds no one.
    block.remove("URV2")
    assert block.limit_m("URV1") == math.inf


def test_on_a_ring_ahead_wraps_past_the_end_of_the_lap() -> None:
    block = MovingBlock(margin_m=20.0, ring_length_m={"ring": RING_M}.get)
    place(block, "URV1", 5600.0)
    place(block, "URV2", 150.0)
    # URV2's rear (142) is 5700 − 5602 + 142 = 240 m ahead of URV1's front (5602).
    assert block.gap_m("URV1") == pytest.approx(240.0)
    assert block.limit_m("URV1") == pytest.approx(5602.0 + 220.0)
    # And URV1 is ahead of URV2, the long way round.
    assert block.gap_m("URV2") == pytest.approx(5592.0 - 152.0)


def test_trains_on_other_lines_do_not_bound_each_other() -> None:
    block = MovingBlock(margin_m=10.0)
    place(block, "URV1", 100.0, line_id="a")
    place(block, "URV2", 200.0, line_id="b")
    assert block.limit_m("URV1") == math.inf
    assert [e.vehicle_id for e in block.trains("a")] == ["URV1"]


def test_overlapping_reports_leave_no_room_at_all() -> None:
    """Two reports that cannot both be right (intervals of 40 m, 10 m apart): the follower
    may not go beyond its own front end."""
    block = MovingBlock(margin_m=0.0, ring_length_m={"ring": RING_M}.get)
    place(block, "URV1", 100.0, confidence_m=40.0)
    place(block, "URV2", 110.0, confidence_m=40.0)
    assert block.gap_m("URV1") < 0.0
    own, limit = block.extent("URV1"), block.limit_m("URV1")
    assert own is not None
    assert limit is not None
    assert limit < own.front_m


def test_a_rear_end_never_moves_backwards() -> None:
    """A wider interval (or a balise's correction) moves the estimate back: the train itself did
    not move, and the train behind it was granted up to its old rear end."""
    block = MovingBlock(margin_m=0.0)
    place(block, "URV1", 100.0)
    place(block, "URV2", 600.0)
    before = block.limit_m("URV1")
    place(block, "URV2", 600.0, confidence_m=30.0)
    assert block.limit_m("URV1") == before
    assert block.extent("URV2").front_m == 630.0  # type: ignore[union-attr]


def test_a_silent_train_still_bounds_the_train_behind_it() -> None:
    """Its last rear end stays valid however old: a train in FS does not move backwards."""
    block = MovingBlock(margin_m=30.0)
    place(block, "URV2", 600.0)
    place(block, "URV1", 100.0)
    for _ in range(3):
        place(block, "URV1", 100.0)  # only the follower keeps reporting
    assert block.limit_m("URV1") == pytest.approx(562.0)


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(ValueError, match="margin"):
        MovingBlock(margin_m=-1.0)
    broken = MovingBlock(margin_m=1.0, ring_length_m={"ring": 0.0}.get)
    with pytest.raises(ValueError, match="length"):
        broken.ring_length_m("ring")


@given(
    decimetres=st.lists(
        st.integers(min_value=0, max_value=int(RING_M * 10) - 1),
        min_size=2,
        max_size=6,
        unique=True,
    )
)
def test_on_a_ring_every_limit_lies_behind_the_rear_of_the_train_ahead(
    decimetres: list[int],
) -> None:
    """Whatever the places, each train's limit lies the margin behind its leader's rear end,
    and the leaders form one cycle round the ring (each train leads exactly one other)."""
    block = MovingBlock(margin_m=25.0, ring_length_m={"ring": RING_M}.get)
    for index, position in enumerate(decimetres):
        place(block, f"T{index}", position / 10.0, confidence_m=1.0)
    extents = {e.vehicle_id: e for e in block.trains("ring")}
    leaders: list[str] = []
    for vehicle_id, own in extents.items():
        ahead = block.train_ahead(vehicle_id)
        assert ahead is not None  # every train has one ahead on a ring of two or more
        leaders.append(ahead.vehicle_id)
        limit = block.limit_m(vehicle_id)
        assert limit is not None
        between_rears = (ahead.rear_m - own.rear_m) % RING_M
        assert 0.0 < between_rears < RING_M
        to_rear = between_rears - (own.front_m - own.rear_m)
        assert limit == pytest.approx(own.front_m + to_rear - 25.0, abs=1e-6)
    assert len(set(leaders)) == len(leaders)


def test_the_extent_is_a_value() -> None:
    a = TrainExtent(vehicle_id="U", line_id="l", front_m=1.0, rear_m=0.0, reported_at_s=0.0)
    assert a == TrainExtent(vehicle_id="U", line_id="l", front_m=1.0, rear_m=0.0, reported_at_s=0.0)
