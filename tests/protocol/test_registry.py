"""The key-space registry: keys, wildcards, parsing and payload checks."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocol import KeyExpressionError, PayloadError
from protocol.registry import ALIVE_ONBOARD, COMMAND, SESSION, STATUS, TOPICS, Delivery


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
    assert all(topic.reply_type is not None for topic in TOPICS if topic.delivery is Delivery.QUERY)


def test_every_topic_is_documented_in_the_keyspace_page() -> None:
    page = (Path(__file__).resolve().parents[2] / "docs" / "keyspace.md").read_text()
    missing = [t.key_template for t in TOPICS if f"`{t.key_template}`" not in page]
    assert missing == []
