"""Wire contracts shared by ATO-TS (trackside) and ATO-OB (onboard).

The only package both sides import: message models (:mod:`protocol.messages`), the Zenoh key-space
registry (:mod:`protocol.registry`), typed Zenoh helpers (:mod:`protocol.bus`), the Zenoh
configuration builder (:mod:`protocol.zenoh_config`), the router (:mod:`protocol.router`) and
the sensor-fusion UDP codecs (:mod:`protocol.udp`). Errors are listed in
:mod:`protocol._exceptions`.
"""

from protocol._exceptions import (
    CountMismatchError,
    DatagramEncodeError,
    KeyExpressionError,
    LengthMismatchError,
    MalformedDatagramError,
    PayloadError,
    ProtocolError,
    RequestTimeoutError,
    TransportError,
    TruncatedDatagramError,
    UnknownSensorTypeError,
)
from protocol.bus import (
    LivelinessWatcher,
    TopicMonitor,
    TopicStats,
    TypedPublisher,
    TypedQueryable,
    TypedSubscriber,
    declare_liveliness,
    request,
    request_async,
)
from protocol.registry import TOPICS, Delivery, Direction, QueryTopic, RegistryTopic, Topic
from protocol.zenoh_config import (
    DEFAULT_ROUTER_ENDPOINT,
    TlsFiles,
    ZenohSettings,
    open_session,
    zenoh_config,
)

__all__ = [
    "DEFAULT_ROUTER_ENDPOINT",
    "TOPICS",
    "CountMismatchError",
    "DatagramEncodeError",
    "Delivery",
    "Direction",
    "KeyExpressionError",
    "LengthMismatchError",
    "LivelinessWatcher",
    "MalformedDatagramError",
    "PayloadError",
    "ProtocolError",
    "QueryTopic",
    "RegistryTopic",
    "RequestTimeoutError",
    "Topic",
    "TopicMonitor",
    "TlsFiles",
    "TopicStats",
    "TransportError",
    "TruncatedDatagramError",
    "TypedPublisher",
    "TypedQueryable",
    "TypedSubscriber",
    "UnknownSensorTypeError",
    "ZenohSettings",
    "declare_liveliness",
    "open_session",
    "request",
    "request_async",
    "zenoh_config",
]
