"""Domain errors raised by the trackside services; only the routes turn them into HTTP.

::

    TracksideError (Exception)
    ├── AuthenticationError      bad credentials or token
    ├── PermissionDeniedError    role too low for the action
    ├── NotFoundError (LookupError)
    ├── ConflictError            the resource exists or is held by someone else
    └── InvalidRequestError (ValueError)   values the service cannot act on (a bad range)

The services also let trackdb's errors through (``trackdb.LineValidationError``,
``trackdb.LineNotFoundError``, ``trackdb.LineConflictError``); the routes map them too.
"""

from __future__ import annotations

__all__ = [
    "AuthenticationError",
    "ConflictError",
    "InvalidRequestError",
    "NotFoundError",
    "PermissionDeniedError",
    "TracksideError",
]


class TracksideError(Exception):
    """Base of the trackside's domain errors."""


class AuthenticationError(TracksideError):
    """Credentials or token not valid."""


class PermissionDeniedError(TracksideError):
    """The user's role does not allow the action."""


class NotFoundError(TracksideError, LookupError):
    """No such resource."""


class ConflictError(TracksideError):
    """The resource already exists or is held by another user."""


class InvalidRequestError(TracksideError, ValueError):
    """The request's values are well-formed but the service cannot act on them."""
