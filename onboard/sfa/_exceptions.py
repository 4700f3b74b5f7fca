"""The sensor-fusion package's exception tree, documented in one place.

- :class:`SfaError` — base of everything this package raises on purpose.
  - :class:`NotInitialisedError` — the filter was asked for an estimate before a GROUND_TRUTH.
  - :class:`AddressError` — a ``HOST:PORT`` option that does not parse.

Malformed datagrams never raise out of the listener: they are dropped and counted by reason.
"""

from __future__ import annotations

from onboard._exceptions import OnboardError

__all__ = ["AddressError", "NotInitialisedError", "SfaError"]


class SfaError(OnboardError):
    """Base of the sensor-fusion errors."""


class NotInitialisedError(SfaError, RuntimeError):
    """The filter has not been initialised by a GROUND_TRUTH packet."""


class AddressError(SfaError, ValueError):
    """A ``HOST:PORT`` address that does not parse."""
