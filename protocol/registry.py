"""The Zenoh key-space registry: one table, key expression → payload → direction → rate → delivery.

Everything exchanged between ATO-TS and ATO-OB goes through a :class:`Topic` of this table, so
that the payload model, the direction, the expected rate and the delivery discipline of a key are
written down once. Keys live under ``ato/``; ``{vehicle}`` and ``{instance}`` are filled in by
:meth:`Topic.key`. The table is documented for operators in ``docs/keyspace.md``.

Deliveries:

- ``LATEST``: only the newest value matters (status); senders drop under congestion and
  receivers keep the latest per key.
- ``FIFO``: every message matters, in order (events, journey profiles); senders block under
  congestion and receivers queue.
- ``QUERY``: a request answered by a reply (commands, session handshake), delivered reliably.
  Such a topic is a :class:`QueryTopic`, typed by its request and its reply.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING, Generic, TypeAlias, TypeVar

from pydantic import TypeAdapter, ValidationError

from protocol import messages as m
from protocol._exceptions import KeyExpressionError, PayloadError

if TYPE_CHECKING:
    # For the type checker only: the annotations are strings at run time (PEP 563), and the
    # pinned pydantic does not guarantee a typing_extensions recent enough to have TypeForm.
    from typing_extensions import TypeForm

__all__ = [
    "ALIVE_ONBOARD",
    "ALIVE_TRACKSIDE",
    "COMMAND",
    "EVENT",
    "JOURNEY_PROFILE",
    "JOURNEY_PROFILE_ACK",
    "LINE_DOCUMENT",
    "LINE_VERSION",
    "MOVEMENT_AUTHORITY",
    "MOVEMENT_AUTHORITY_ACK",
    "MOVEMENT_AUTHORITY_CURRENT",
    "SESSION",
    "SESSION_TERMINATION",
    "SPEED_RESTRICTION",
    "STATUS_ACK",
    "STATUS",
    "TOPICS",
    "Delivery",
    "Direction",
    "QueryTopic",
    "RegistryTopic",
    "Topic",
]

T = TypeVar("T")
Request = TypeVar("Request")
Reply = TypeVar("Reply")

_PLACEHOLDER = re.compile(r"\{([a-z_]+)\}")
_CHUNK = r"([A-Za-z0-9_-]+)"
MAX_CACHED_KEYS = 65_536
"""A topic keeps at most this many concrete keys made (then starts afresh)."""


class Direction(StrEnum):
    ONBOARD_TO_TRACKSIDE = "ob->ts"
    TRACKSIDE_TO_ONBOARD = "ts->ob"
    ANY = "any"


class Delivery(StrEnum):
    LATEST = "latest"
    FIFO = "fifo"
    QUERY = "query"


def _alternate(parts: list[str]) -> list[tuple[bool, str]]:
    """Pairs each piece of ``re.split`` output with whether it was a captured chunk name."""
    return [(index % 2 == 1, part) for index, part in enumerate(parts)]


@dataclass(frozen=True)
class Topic(Generic[T]):
    """One entry of the key-space registry: a published topic (``LATEST`` or ``FIFO``).

    Parameters
    ----------
    name
        Short name used in logs and counters.
    key_template
        Key expression with ``{chunk}`` markers for its variable chunks.
    payload_type
        Model (or annotated union) of the payload; of the request for a :class:`QueryTopic`.
    direction
        Which side publishes (or queries).
    delivery
        Latest value, reliable FIFO, or query/reply (the last for a :class:`QueryTopic` only).
    rate_hz
        Expected publication rate [Hz]; ``None`` for sporadic topics.
    """

    name: str
    key_template: str
    payload_type: TypeForm[T]
    direction: Direction
    delivery: Delivery
    rate_hz: float | None = None
    _adapter: TypeAdapter[T] = field(init=False, repr=False, compare=False)
    _pattern: re.Pattern[str] = field(init=False, repr=False, compare=False)
    _chunk_names: tuple[str, ...] = field(init=False, repr=False, compare=False)
    _keys: dict[tuple[tuple[str, str], ...], str] = field(init=False, repr=False, compare=False)
    """Concrete keys made so far (a trackside makes one per vehicle and topic, thousands of
    times a second with a large fleet)."""
    _parsed: dict[str, dict[str, str]] = field(init=False, repr=False, compare=False)
    """Concrete keys parsed so far (a trackside parses each status report's key)."""

    def __post_init__(self) -> None:
        if (self.delivery is Delivery.QUERY) != isinstance(self, QueryTopic):
            raise TypeError(f"{self.name}: a QUERY topic is a QueryTopic, and only it is")
        object.__setattr__(self, "_adapter", TypeAdapter(self.payload_type))
        parts = _PLACEHOLDER.split(self.key_template)
        regex = "".join(_CHUNK if odd else re.escape(part) for odd, part in _alternate(parts))
        object.__setattr__(self, "_pattern", re.compile(f"^{regex}$"))
        object.__setattr__(self, "_chunk_names", tuple(_PLACEHOLDER.findall(self.key_template)))
        object.__setattr__(self, "_keys", {})
        object.__setattr__(self, "_parsed", {})

    @property
    def chunk_names(self) -> tuple[str, ...]:
        return self._chunk_names

    @property
    def period_s(self) -> float | None:
        return None if self.rate_hz is None else 1.0 / self.rate_hz

    def key(self, **chunks: str) -> str:
        """The concrete key for these chunk values; a missing or bad chunk raises."""
        known = tuple(chunks.items())
        key = self._keys.get(known)
        if key is None:
            key = self._make_key(chunks)
            if len(self._keys) >= MAX_CACHED_KEYS:
                self._keys.clear()
            self._keys[known] = key
        return key

    def _make_key(self, chunks: dict[str, str]) -> str:
        if set(chunks) != set(self.chunk_names):
            raise KeyExpressionError(
                f"{self.name}: expected chunks {self.chunk_names}, got {tuple(chunks)}"
            )
        for name, value in chunks.items():
            if not re.fullmatch(_CHUNK, value):
                raise KeyExpressionError(f"{self.name}: bad {name} chunk {value!r}")
        return self.key_template.format(**chunks)

    def wildcard(self, **chunks: str) -> str:
        """A key expression matching this topic for the given chunks and any others."""
        filled = {name: chunks.get(name, "*") for name in self.chunk_names}
        return self.key_template.format(**filled)

    def parse(self, key: str) -> dict[str, str]:
        """The chunk values of a concrete key of this topic."""
        chunks = self._parsed.get(key)
        if chunks is None:
            match = self._pattern.match(key)
            if match is None:
                raise KeyExpressionError(f"{key!r} is not a {self.name} key ({self.key_template})")
            chunks = dict(zip(self.chunk_names, match.groups(), strict=True))
            if len(self._parsed) >= MAX_CACHED_KEYS:
                self._parsed.clear()
            self._parsed[key] = chunks
        return dict(chunks)

    def encode(self, message: T) -> bytes:
        return self._adapter.dump_json(message)

    def decode(self, payload: bytes) -> T:
        try:
            return self._adapter.validate_json(payload)
        except ValidationError as exc:
            raise PayloadError(f"{self.name}: {exc.error_count()} error(s): {exc}") from exc


@dataclass(frozen=True)
class QueryTopic(Topic[Request], Generic[Request, Reply]):
    """A registry entry delivered as a query: a ``Request`` answered by a ``Reply``.

    ``payload_type`` is the request's model; ``reply_type`` (keyword-only) the reply's. The two
    type parameters carry through :func:`protocol.bus.request`, :func:`protocol.bus.request_async`
    and :class:`protocol.bus.TypedQueryable`, so that a caller gets the reply's own model.
    """

    reply_type: TypeForm[Reply] = field(kw_only=True)
    _reply_adapter: TypeAdapter[Reply] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "_reply_adapter", TypeAdapter(self.reply_type))

    def encode_reply(self, reply: Reply) -> bytes:
        return self._reply_adapter.dump_json(reply)

    def decode_reply(self, payload: bytes) -> Reply:
        try:
            return self._reply_adapter.validate_json(payload)
        except ValidationError as exc:
            raise PayloadError(f"{self.name} reply: {exc}") from exc


STATUS: Topic[m.StatusReport] = Topic(
    "status",
    "ato/ob/{vehicle}/status",
    m.StatusReport,
    Direction.ONBOARD_TO_TRACKSIDE,
    Delivery.LATEST,
    rate_hz=5.0,
)
EVENT: Topic[m.Event] = Topic(
    "event",
    "ato/ob/{vehicle}/event",
    m.Event,
    Direction.ONBOARD_TO_TRACKSIDE,
    Delivery.FIFO,
)
COMMAND: QueryTopic[m.Command, m.CommandAck] = QueryTopic(
    "command",
    "ato/ob/{vehicle}/command",
    m.Command,
    Direction.TRACKSIDE_TO_ONBOARD,
    Delivery.QUERY,
    reply_type=m.CommandAck,
)
JOURNEY_PROFILE: Topic[m.JourneyProfile] = Topic(
    "journey_profile",
    "ato/ts/{vehicle}/journey_profile",
    m.JourneyProfile,
    Direction.TRACKSIDE_TO_ONBOARD,
    Delivery.FIFO,
)
JOURNEY_PROFILE_ACK: Topic[m.JourneyProfileAck] = Topic(
    "journey_profile_ack",
    "ato/ob/{vehicle}/journey_profile_ack",
    m.JourneyProfileAck,
    Direction.ONBOARD_TO_TRACKSIDE,
    Delivery.FIFO,
)
LINE_VERSION: QueryTopic[m.LineVersionRequest, m.LineVersionReply] = QueryTopic(
    "line_version",
    "ato/ts/line/{line}/version",
    m.LineVersionRequest,
    Direction.ONBOARD_TO_TRACKSIDE,
    Delivery.QUERY,
    reply_type=m.LineVersionReply,
)
LINE_DOCUMENT: QueryTopic[m.LineDocumentRequest, m.LineDocumentReply] = QueryTopic(
    "line_document",
    "ato/ts/line/{line}/document",
    m.LineDocumentRequest,
    Direction.ONBOARD_TO_TRACKSIDE,
    Delivery.QUERY,
    reply_type=m.LineDocumentReply,
)
SESSION: QueryTopic[m.SessionRequest, m.SessionResponse] = QueryTopic(
    "session",
    "ato/ts/session/{vehicle}",
    m.SessionRequest,
    Direction.ONBOARD_TO_TRACKSIDE,
    Delivery.QUERY,
    reply_type=m.SessionResponse,
)
STATUS_ACK: Topic[m.StatusAck] = Topic(
    "status_ack",
    "ato/ts/{vehicle}/status_ack",
    m.StatusAck,
    Direction.TRACKSIDE_TO_ONBOARD,
    Delivery.FIFO,
)
SESSION_TERMINATION: Topic[m.SessionTermination] = Topic(
    "session_termination",
    "ato/session/{vehicle}/termination",
    m.SessionTermination,
    Direction.ANY,
    Delivery.FIFO,
)
MOVEMENT_AUTHORITY: Topic[m.MovementAuthorityMessage] = Topic(
    "movement_authority",
    "ato/ts/rbc/{vehicle}/ma",
    m.MovementAuthorityMessage,
    Direction.TRACKSIDE_TO_ONBOARD,
    Delivery.FIFO,
)
SPEED_RESTRICTION: Topic[m.SpeedRestrictionMessage] = Topic(
    "speed_restriction",
    "ato/ts/rbc/{vehicle}/tsr",
    m.SpeedRestrictionMessage,
    Direction.TRACKSIDE_TO_ONBOARD,
    Delivery.FIFO,
)
MOVEMENT_AUTHORITY_CURRENT: QueryTopic[m.MovementAuthorityRequest, m.MovementAuthorityReply] = (
    QueryTopic(
        "movement_authority_current",
        "ato/ts/rbc/{vehicle}/current_ma",
        m.MovementAuthorityRequest,
        Direction.ONBOARD_TO_TRACKSIDE,
        Delivery.QUERY,
        reply_type=m.MovementAuthorityReply,
    )
)
MOVEMENT_AUTHORITY_ACK: Topic[m.MovementAuthorityAck] = Topic(
    "movement_authority_ack",
    "ato/ob/{vehicle}/ma_ack",
    m.MovementAuthorityAck,
    Direction.ONBOARD_TO_TRACKSIDE,
    Delivery.FIFO,
)

ALIVE_ONBOARD = "ato/alive/ob/{vehicle}"
"""Liveliness token of an onboard process (CONTRACT.md §5)."""
ALIVE_TRACKSIDE = "ato/alive/ts/{instance}"
"""Liveliness token of a trackside instance (CONTRACT.md §5)."""

RegistryTopic: TypeAlias = (
    Topic[m.StatusReport]
    | Topic[m.Event]
    | QueryTopic[m.Command, m.CommandAck]
    | Topic[m.JourneyProfile]
    | Topic[m.JourneyProfileAck]
    | QueryTopic[m.LineVersionRequest, m.LineVersionReply]
    | QueryTopic[m.LineDocumentRequest, m.LineDocumentReply]
    | QueryTopic[m.SessionRequest, m.SessionResponse]
    | Topic[m.StatusAck]
    | Topic[m.SessionTermination]
    | Topic[m.MovementAuthorityMessage]
    | QueryTopic[m.MovementAuthorityRequest, m.MovementAuthorityReply]
    | Topic[m.MovementAuthorityAck]
    | Topic[m.SpeedRestrictionMessage]
)
"""One topic of the table, whichever: what iterating :data:`TOPICS` gives. A union of the
entries' own types, so that decoding with an entry not known in advance still gives one of the
payload models (and encoding needs a message every entry takes, which none is)."""

TOPICS: tuple[RegistryTopic, ...] = (
    STATUS,
    EVENT,
    COMMAND,
    JOURNEY_PROFILE,
    JOURNEY_PROFILE_ACK,
    LINE_VERSION,
    LINE_DOCUMENT,
    SESSION,
    STATUS_ACK,
    SESSION_TERMINATION,
    MOVEMENT_AUTHORITY,
    MOVEMENT_AUTHORITY_CURRENT,
    MOVEMENT_AUTHORITY_ACK,
    SPEED_RESTRICTION,
)
