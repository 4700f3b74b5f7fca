"""The exception tree of the ``protocol`` package, in one place.

::

    ProtocolError (Exception)
    ├── MalformedDatagramError (ValueError)     a UDP datagram that breaks CONTRACT.md §3
    │   ├── TruncatedDatagramError              shorter than the 5-byte header
    │   ├── LengthMismatchError                 length differs from 5 + 4·N_INT + 8·N_DOUBLE
    │   ├── UnknownSensorTypeError              SENSOR_TYPE not in the table
    │   └── CountMismatchError                  N_INT / N_DOUBLE do not match the type
    ├── DatagramEncodeError (ValueError)        a value that cannot be put on the wire
    ├── PayloadError (ValueError)               a Zenoh payload that does not validate
    ├── KeyExpressionError (ValueError)         a key that does not fit a registry topic
    └── TransportError (RuntimeError)           a Zenoh failure, translated at the boundary
        └── RequestTimeoutError (TimeoutError)  no reply to a query within its timeout

Foreign errors (``struct.error``, ``pydantic.ValidationError``, ``zenoh.ZError``) are caught where
they arise and re-raised as one of these with ``raise ... from exc``.
"""

from __future__ import annotations

__all__ = [
    "CountMismatchError",
    "DatagramEncodeError",
    "KeyExpressionError",
    "LengthMismatchError",
    "MalformedDatagramError",
    "PayloadError",
    "ProtocolError",
    "RequestTimeoutError",
    "TransportError",
    "TruncatedDatagramError",
    "UnknownSensorTypeError",
]


class ProtocolError(Exception):
    """Base of every error raised by ``protocol``."""


class MalformedDatagramError(ProtocolError, ValueError):
    """A datagram that does not follow the byte layout of CONTRACT.md §3."""


class TruncatedDatagramError(MalformedDatagramError):
    """The datagram is shorter than its fixed header."""


class LengthMismatchError(MalformedDatagramError):
    """The datagram's length differs from what its header announces."""


class UnknownSensorTypeError(MalformedDatagramError):
    """The SENSOR_TYPE byte names no known sensor."""


class CountMismatchError(MalformedDatagramError):
    """N_INT or N_DOUBLE differ from the counts fixed for the sensor type."""


class DatagramEncodeError(ProtocolError, ValueError):
    """A value is out of the range its wire field can carry."""


class PayloadError(ProtocolError, ValueError):
    """A Zenoh payload that is not valid JSON for its topic's model."""


class KeyExpressionError(ProtocolError, ValueError):
    """A key expression that does not match the registry topic it was parsed against."""


class TransportError(ProtocolError, RuntimeError):
    """Zenoh refused an operation (open, declare, put, get)."""


class RequestTimeoutError(TransportError, TimeoutError):
    """A query got no reply within its timeout."""
