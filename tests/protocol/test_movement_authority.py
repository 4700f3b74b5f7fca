"""RBC movement-authority messages: their rules, and that the onboard can take every valid one."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given
from pydantic import ValidationError

from onboard.etcs import EtcsOnboard, MaChange
from onboard.rbc_messages import authority_from_extent
from protocol import messages as m
from protocol.registry import MOVEMENT_AUTHORITY, MOVEMENT_AUTHORITY_CURRENT
from tests.protocol.strategies import movement_authority_messages, movement_authority_replies
from trackdb import TrackMap, load_seed_line

GOOD_EXTENT: dict[str, Any] = {"start_m": 100.0, "end_of_authority_m": 900.0}


def _message(**overrides: Any) -> dict[str, Any]:
    return {
        "vehicle_id": "URV1",
        "ma_id": 1,
        "change": "issued",
        "issued_at_s": 0.0,
        "line_id": "milano-bologna",
        "line_version": "v1",
        "authority": GOOD_EXTENT,
    } | overrides


@given(movement_authority_messages())
def test_every_granted_message_makes_an_onboard_movement_authority(
    message: m.MovementAuthorityMessage,
) -> None:
    if message.authority is not None:
        authority = authority_from_extent(message.authority)
        assert authority.reference_m + authority.end_of_authority_m == pytest.approx(
            message.authority.end_of_authority_m, rel=1e-9, abs=1e-6
        )


def test_the_onboard_applies_an_extension_and_a_shortening() -> None:
    etcs = EtcsOnboard(TrackMap(load_seed_line("milano-bologna")), position_m=150.0)
    first = m.MovementAuthorityExtent(start_m=100.0, end_of_authority_m=900.0, overlap_m=50.0)
    longer = first.model_copy(update={"end_of_authority_m": 1500.0})
    shorter = m.MovementAuthorityExtent(start_m=100.0, end_of_authority_m=600.0)
    changes = [
        etcs.receive_movement_authority(authority_from_extent(extent), now_s)
        for now_s, extent in enumerate((first, longer, shorter))
    ]
    assert changes == [MaChange.NEW, MaChange.EXTENDED, MaChange.SHORTENED]
    held = etcs.movement_authority
    assert held is not None
    assert held.end_of_authority_m == pytest.approx(600.0)
    assert held.supervised_location_m == pytest.approx(shorter.supervised_location_m)


def test_supervised_location_is_overlap_else_danger_point_else_eoa() -> None:
    assert m.MovementAuthorityExtent(**GOOD_EXTENT).supervised_location_m == 900.0
    with_dp = m.MovementAuthorityExtent(**GOOD_EXTENT, danger_point_m=20.0)
    assert with_dp.supervised_location_m == 920.0
    with_ol = m.MovementAuthorityExtent(**GOOD_EXTENT, danger_point_m=20.0, overlap_m=70.0)
    assert with_ol.supervised_location_m == 970.0


@pytest.mark.parametrize(
    ("changes", "needle"),
    [
        ({"end_of_authority_m": 100.0}, "must lie beyond the start"),
        ({"end_of_authority_m": float("nan")}, "finite"),
        ({"danger_point_m": 50.0, "overlap_m": 10.0}, "beyond the danger point"),
        ({"overlap_timer_s": 30.0}, "needs an overlap"),
        ({"sections": [{"length_m": 300.0}, {"length_m": 400.0}]}, "add up to 700.0 m"),
        ({"sections": [{"length_m": 0.0}]}, "greater than 0"),
        ({"release_speed_mps": -1.0}, "greater than or equal to 0"),
        ({"track_description_m": 0.0}, "greater than 0"),
        ({"surprise": 1}, "Extra inputs"),
    ],
)
def test_bad_extents_are_refused(changes: dict[str, Any], needle: str) -> None:
    with pytest.raises(ValidationError, match=needle):
        m.MovementAuthorityExtent.model_validate(GOOD_EXTENT | changes)


def test_sections_that_add_up_are_taken() -> None:
    sections = [{"length_m": 300.0, "timer_s": 60.0, "timer_stop_m": 250.0}, {"length_m": 500.0}]
    extent = m.MovementAuthorityExtent.model_validate(GOOD_EXTENT | {"sections": sections})
    assert extent.sections[0].timer_s == 60.0


def test_revoked_carries_no_authority_and_granted_one() -> None:
    m.MovementAuthorityMessage.model_validate(_message(change="revoked", authority=None))
    with pytest.raises(ValidationError, match="revoked MA carries no authority"):
        m.MovementAuthorityMessage.model_validate(_message(change="revoked"))
    with pytest.raises(ValidationError, match="revoked MA carries no authority"):
        m.MovementAuthorityMessage.model_validate(_message(authority=None))
    for field, value in (("ma_id", 0), ("line_version", ""), ("vehicle_id", "a/b")):
        with pytest.raises(ValidationError):
            m.MovementAuthorityMessage.model_validate(_message(**{field: value}))


@given(movement_authority_replies)
def test_current_ma_reply_round_trip(reply: m.MovementAuthorityReply) -> None:
    assert (
        MOVEMENT_AUTHORITY_CURRENT.decode_reply(MOVEMENT_AUTHORITY_CURRENT.encode_reply(reply))
        == reply
    )


def test_keys() -> None:
    assert MOVEMENT_AUTHORITY.key(vehicle="URV1") == "ato/ts/rbc/URV1/ma"
    assert MOVEMENT_AUTHORITY_CURRENT.key(vehicle="URV1") == "ato/ts/rbc/URV1/current_ma"
    assert MOVEMENT_AUTHORITY.parse("ato/ts/rbc/URV-2/ma") == {"vehicle": "URV-2"}
