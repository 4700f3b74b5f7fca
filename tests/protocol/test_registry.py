"""The key-space registry: keys, wildcards, parsing and payload checks."""

from __future__ import annotations

from pathlib import Path
from typing import get_args

import pytest

from protocol import KeyExpressionError, PayloadError, registry
from protocol import messages as m
from protocol.registry import (
    ALIVE_ONBOARD,
    COMMAND,
    LINE_VERSION,
    MOVEMENT_AUTHORITY_CURRENT,
    SESSION,
    STATUS,
    TOPICS,
    Delivery,
    Direction,
    QueryTopic,
    Topic,
)


def test_keys_are_under_ato_and_unique() -> None:
    templates = [topic.key_template for topic in TOPICS]
    assert len(set(templates)) == len(templates)
    assert all(template.startswith("ato/") for template in templates)
    assert ALIVE_ONBOARD.format(vehicle="URV1") == "ato/alive/ob/URV1"


def test_key_wildcard_and_parse() -> None:
    assert STATUS.key(vehicle="URV1") == "ato/ob/URV1/status"
    assert STATUS.wildcard() == "ato/ob/*/status"
    assert STATUS.parse("ato/ob/URV-2/status") == {"vehicle": "URV-2"}
    assert SESSION.parse("ato/ts/session/URV1") == {"vehicle": "URV1"}


def test_a_parsed_key_is_cached_and_each_caller_gets_its_own_chunks() -> None:
    first = STATUS.parse("ato/ob/URV-7/status")
    first["vehicle"] = "changed by its caller"
    assert STATUS.parse("ato/ob/URV-7/status") == {"vehicle": "URV-7"}
    with pytest.raises(KeyExpressionError):  # a refused key is refused again, not cached
        STATUS.parse("ato/ob/a/b/status")
    with pytest.raises(KeyExpressionError):
        STATUS.parse("ato/ob/a/b/status")


@pytest.mark.parametrize(
    "key", ["ato/ob/URV1/event", "ato/ob/a/b/status", "ato/ob//status", "xato/ob/URV1/status"]
)
def test_parse_refuses_other_keys(key: str) -> None:
    with pytest.raises(KeyExpressionError):
        STATUS.parse(key)


@pytest.mark.parametrize("chunks", [{}, {"vehicle": "a/b"}, {"vehicle": "*"}, {"train": "x"}])
def test_key_refuses_bad_chunks(chunks: dict[str, str]) -> None:
    with pytest.raises(KeyExpressionError):
        STATUS.key(**chunks)


@pytest.mark.parametrize("payload", [b"", b"{", b"[]", b'{"vehicle_id": "URV1"}', b"\xff\xfe"])
def test_decode_raises_payload_error(payload: bytes) -> None:
    with pytest.raises(PayloadError):
        STATUS.decode(payload)
    with pytest.raises(PayloadError):
        COMMAND.decode_reply(payload)


def test_rates_and_deliveries() -> None:
    assert STATUS.delivery is Delivery.LATEST
    assert STATUS.rate_hz == 5.0
    assert STATUS.period_s == pytest.approx(0.2)
    assert COMMAND.delivery is Delivery.QUERY
    queries = [topic for topic in TOPICS if topic.delivery is Delivery.QUERY]
    assert all(isinstance(topic, QueryTopic) for topic in queries)
    assert [topic for topic in TOPICS if isinstance(topic, QueryTopic)] == queries


def test_query_topics_carry_their_reply_model() -> None:
    assert COMMAND.payload_type is m.Command
    assert COMMAND.reply_type is m.CommandAck
    assert LINE_VERSION.reply_type is m.LineVersionReply
    assert SESSION.reply_type is m.SessionResponse
    assert MOVEMENT_AUTHORITY_CURRENT.reply_type is m.MovementAuthorityReply
    assert not hasattr(STATUS, "reply_type")


def test_a_reply_of_another_model_does_not_validate() -> None:
    ack = m.CommandAck(vehicle_id="URV1", command_id=1, accepted=True, sim_time_s=0.0)
    assert COMMAND.decode_reply(COMMAND.encode_reply(ack)) == ack
    with pytest.raises(PayloadError, match="command reply"):
        COMMAND.decode_reply(LINE_VERSION.encode_reply(m.LineVersionReply(line_id="x")))


def test_query_delivery_and_query_topic_go_together() -> None:
    with pytest.raises(TypeError, match="QueryTopic"):
        Topic("x", "ato/x", m.Command, Direction.ANY, Delivery.QUERY)
    with pytest.raises(TypeError, match="QueryTopic"):
        QueryTopic("x", "ato/x", m.Command, Direction.ANY, Delivery.FIFO, reply_type=m.CommandAck)


def test_every_topic_of_the_module_is_in_the_table() -> None:
    declared = {name: t for name, t in vars(registry).items() if isinstance(t, Topic)}
    assert set(declared) <= set(registry.__all__)
    assert {id(topic) for topic in declared.values()} == {id(topic) for topic in TOPICS}


def test_every_topic_is_documented_in_the_keyspace_page() -> None:
    page = (Path(__file__).resolve().parents[2] / "docs" / "keyspace.md").read_text()
    missing = [t.key_template for t in TOPICS if f"`{t.key_template}`" not in page]
    assert missing == []


def test_the_keyspace_page_names_each_topic_s_payload_and_reply() -> None:
    page = (Path(__file__).resolve().parents[2] / "docs" / "keyspace.md").read_text()
    rows = {line.split("|")[1].strip(" `"): line for line in page.splitlines() if "| `ato/" in line}
    for topic in TOPICS:
        row = rows[topic.key_template]
        assert row.split("|")[2].strip().startswith(f"`{topic.payload_type.__name__}`")
        if isinstance(topic, QueryTopic):
            first, *others = _model_names(topic.reply_type)
            assert f"reply `{first}`" in row, topic.name
            assert all(f"`{name}`" in row for name in others), topic.name


def _model_names(model: object) -> list[str]:
    """A model's name, or the names of an annotated union's members."""
    if isinstance(model, type):
        return [model.__name__]
    union, *_metadata = get_args(model)
    return [member.__name__ for member in get_args(union)]
