"""Every wire message survives JSON and back; bad messages are refused."""

from __future__ import annotations

import inspect
from typing import Any, cast

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydantic import ValidationError

from protocol import messages as m
from protocol.registry import TOPICS
from tests.protocol.strategies import STRATEGIES

MESSAGE_MODELS = [
    obj
    for name in m.__all__
    if inspect.isclass(obj := getattr(m, name))
    and issubclass(obj, m.Message)
    and obj is not m.Message
]


def test_every_message_model_has_a_strategy() -> None:
    assert set(MESSAGE_MODELS) == set(STRATEGIES)


@pytest.mark.parametrize("model", MESSAGE_MODELS, ids=lambda model: model.__name__)
def test_round_trip(model: type[m.Message]) -> None:
    @given(STRATEGIES[model])
    def check(message: m.Message) -> None:
        assert model.model_validate_json(message.model_dump_json()) == message

    check()


@given(st.data())
def test_round_trip_through_registry_topics(data: st.DataObject) -> None:
    topic = data.draw(st.sampled_from(TOPICS))
    # A payload type is a TypeForm, wider than a class; every topic's is a message model.
    strategy: Any = STRATEGIES.get(cast(type[m.Message], topic.payload_type))
    message = data.draw(strategy)
    assert topic.decode(topic.encode(message)) == message


SESSION_RESPONSE_MODELS: list[type[m.Message]] = [m.SessionAccept, m.SessionReject]


@given(st.sampled_from(SESSION_RESPONSE_MODELS).flatmap(lambda t: STRATEGIES[t]))
def test_session_response_union_round_trip(response: m.SessionAccept | m.SessionReject) -> None:
    from protocol.registry import SESSION

    assert SESSION.decode_reply(SESSION.encode_reply(response)) == response


@pytest.mark.parametrize("model", MESSAGE_MODELS, ids=lambda model: model.__name__)
def test_unknown_fields_are_refused(model: type[m.Message]) -> None:
    @given(STRATEGIES[model])
    def check(message: m.Message) -> None:
        document = message.model_dump(mode="json") | {"unexpected": 1}
        with pytest.raises(ValidationError):
            model.model_validate(document)

    check()


def test_schema_version_is_checked() -> None:
    with pytest.raises(ValidationError):
        m.SessionTermination.model_validate(
            {"schema_version": 2, "vehicle_id": "URV1", "by": "onboard", "reason": ""}
        )


def _tp(identifier: str, *, end: bool) -> m.TimingPoint:
    return m.TimingPoint(
        id=identifier,
        position_m=100.0,
        kind=m.TimingPointKind.STOPPING,
        arrival_time_s=60.0,
        end_of_journey=end,
    )


@pytest.mark.parametrize(
    "points",
    [
        (),
        (("a", False),),
        (("a", True), ("b", False)),
        (("a", True), ("b", True)),
    ],
)
def test_journey_profile_needs_one_end_of_journey_last(
    points: tuple[tuple[str, bool], ...],
) -> None:
    with pytest.raises(ValidationError):
        m.JourneyProfile(
            vehicle_id="URV1",
            journey_id="j",
            version=0,
            status=m.JourneyProfileStatus.VALID,
            line_id="bologna-ring",
            track_data_version="x",
            timing_points=tuple(_tp(name, end=end) for name, end in points),
        )


@pytest.mark.parametrize(
    ("field", "value"),
    [("speed_mps", float("nan")), ("position_m", float("inf")), ("seq", -1), ("vehicle_id", "a/b")],
)
def test_status_report_refuses_bad_values(field: str, value: object) -> None:
    good = {
        "vehicle_id": "URV1",
        "seq": 0,
        "sim_time_s": 0.0,
        "line_id": "l",
        "position_m": 0.0,
        "speed_mps": 0.0,
        "acceleration_mps2": 0.0,
        "traction_force_n": 0.0,
        "ato_state": "NA",
        "etcs_mode": "SR",
        "sc_state": "OFF",
    }
    m.StatusReport.model_validate(good)
    with pytest.raises(ValidationError):
        m.StatusReport.model_validate(good | {field: value})
