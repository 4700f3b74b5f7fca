"""Domain errors raised by the trackside services; only the routes turn them into HTTP.

::

    TracksideError (Exception)
    ├── AuthenticationError      bad credentials or token
    ├── PermissionDeniedError    role too low for the action
    ├── NotFoundError (LookupError)
    │   └── NoMovementAuthorityError       the RBC holds no MA for the vehicle
    ├── ConflictError            the resource exists or is held by someone else
    ├── InvalidRequestError (ValueError)   values the service cannot act on (a bad range)
    │   └── MovementAuthorityRefusedError  the RBC cannot issue or change an MA so
    │       └── EndOfAuthorityBehindVehicleError   the EoA at or behind the vehicle's position
    ├── RbcScenarioError (ValueError)      an RBC scenario script that does not load or validate
    ├── VehicleTimeoutError (TimeoutError) the vehicle did not answer a command in time
    └── VehicleLinkError                   a command could not be sent, or its answer was bad

The services also let trackdb's errors through (``trackdb.LineValidationError``,
``trackdb.LineNotFoundError``, ``trackdb.LineConflictError``); the routes map them too.
"""

from __future__ import annotations

__all__ = [
    "AuthenticationError",
    "ConflictError",
    "EndOfAuthorityBehindVehicleError",
    "InvalidRequestError",
    "MovementAuthorityRefusedError",
    "NoMovementAuthorityError",
    "NotFoundError",
    "PermissionDeniedError",
    "RbcScenarioError",
    "TracksideError",
    "VehicleLinkError",
    "VehicleTimeoutError",
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


class NoMovementAuthorityError(NotFoundError):
    """The RBC holds no movement authority for the vehicle (never issued, or revoked)."""


class MovementAuthorityRefusedError(InvalidRequestError):
    """The RBC cannot issue or change the movement authority as asked; nothing was sent."""


class EndOfAuthorityBehindVehicleError(MovementAuthorityRefusedError):
    """The asked EoA lies at or behind the vehicle's last reported front end: it would trip."""

    def __init__(self, message: str, *, end_of_authority_m: float, position_m: float) -> None:
        super().__init__(message)
        self.end_of_authority_m = end_of_authority_m
        self.position_m = position_m


class RbcScenarioError(TracksideError, ValueError):
    """An RBC scenario script that cannot be read or does not validate; lists every problem."""

    def __init__(self, message: str, problems: list[str] | None = None) -> None:
        super().__init__(message)
        self.problems = problems or [message]


class VehicleTimeoutError(TracksideError, TimeoutError):
    """The vehicle did not answer in time; what it did is unknown."""


class VehicleLinkError(TracksideError):
    """The command could not be sent, or the vehicle's answer was an error or not valid."""
