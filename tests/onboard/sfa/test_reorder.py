"""The reorder buffer: order, wrap-around, duplicates, late packets, gaps given up."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from onboard.sfa import ReorderBuffer


def test_releases_in_sequence_order_across_the_wrap() -> None:
    buffer: ReorderBuffer[int] = ReorderBuffer(depth=8, max_wait_s=1.0)
    released: list[int] = []
    for seq in (65534, 0, 65535, 1):
        assert buffer.push(seq, seq, 0.0) is None
        released += buffer.pop_ready(0.0)
    assert released == [65534, 65535, 0, 1]
    assert buffer.next_seq == 2
    assert buffer.lost == 0


def test_duplicates_and_late_packets_are_refused_by_reason() -> None:
    buffer: ReorderBuffer[int] = ReorderBuffer(depth=2, max_wait_s=1.0)
    for seq in (10, 11):
        buffer.push(seq, seq, 0.0)
    assert buffer.pop_ready(0.0) == [10, 11]
    assert buffer.push(11, 11, 0.0) == "duplicate"
    assert buffer.push(14, 14, 0.0) is None
    assert buffer.push(14, 14, 0.0) == "duplicate"
    assert buffer.push(5, 5, 0.0) == "late"


def test_a_gap_is_given_up_after_the_wait_or_when_the_buffer_is_full() -> None:
    buffer: ReorderBuffer[int] = ReorderBuffer(depth=3, max_wait_s=0.05)
    buffer.push(0, 0, 0.0)
    assert buffer.pop_ready(0.0) == [0]
    buffer.push(2, 2, 0.0)
    assert buffer.pop_ready(0.04) == []
    assert buffer.pop_ready(0.05) == [2]
    assert buffer.lost == 1
    for seq in (4, 5, 6, 7):
        buffer.push(seq, seq, 1.0)
    assert buffer.pop_ready(1.0) == [4, 5, 6, 7]
    assert buffer.lost == 2
    assert buffer.push(3, 3, 1.0) == "late"


@given(st.permutations(list(range(12))), st.integers(0, 65535))
def test_any_shuffle_within_the_depth_comes_out_in_order(order: list[int], start: int) -> None:
    buffer: ReorderBuffer[int] = ReorderBuffer(depth=16, max_wait_s=1.0)
    buffer.next_seq = start
    released: list[int] = []
    for offset in order:
        seq = (start + offset) % 65536
        assert buffer.push(seq, offset, 0.0) is None
        released += buffer.pop_ready(0.0)
    assert released == list(range(12))


@pytest.mark.parametrize(
    ("ahead", "refused", "order"),
    [
        # 26 ahead: it waits while 11..35 arrive, then is misplaced; the genuine 36 follows.
        (26, [], [*range(10), *range(11, 41)]),
        # 3 ahead (under 50 ms of packets): released in 13's place, the genuine 13 a duplicate.
        (3, ["duplicate"], [*range(10), 11, 12, 10, *range(14, 41)]),
    ],
)
def test_a_seq_no_corrupted_a_few_numbers_ahead_costs_one_number_not_the_gap(
    ahead: int, refused: list[str], order: list[int]
) -> None:
    """Packet 10's SEQ_NO reads 10 + ``ahead`` (one byte corrupted), packets arriving every
    8 ms. Before, the gap after 10 was given up 50 ms after the corrupted packet arrived, it was
    released and what was left of the gap came ``late``."""
    buffer: ReorderBuffer[int] = ReorderBuffer(depth=16, max_wait_s=0.05)
    released: list[int] = []
    outcomes: list[str] = []
    for seq in range(41):
        arrival_s = 0.008 * seq
        outcome = buffer.push(10 + ahead if seq == 10 else seq, seq, arrival_s)
        if outcome is not None:
            outcomes.append(outcome)
        released += buffer.pop_ready(arrival_s)
    released += buffer.pop_ready(1.0)
    assert outcomes == refused
    assert released == order
    assert (buffer.lost, buffer.misplaced) == (1, 1 if ahead == 26 else 0)
