"""Domain errors raised by the trackside services; only the API turns them into HTTP answers.

One tree, one place. The services raise these and know nothing of HTTP; the status code and
body of each (the table below) are given by the exception handlers that ``create_app``
registers (:mod:`trackside.api.exception_handlers`), never by the routes one by one.

::

    TracksideError (Exception)                                                      HTTP
    ├── AuthenticationError           bad username or password                      401
    │   └── InvalidTokenError         bearer token unknown, revoked, expired, or its
    │                                 user deleted (the answer does not say which)  401
    ├── PermissionDeniedError         role too low for the action                   403
    ├── NotFoundError (LookupError)   no such resource                              404
    │   └── NoMovementAuthorityError  the RBC holds no MA for the vehicle           404
    ├── ConflictError                 the resource exists or is held by another     409
    ├── InvalidRequestError (ValueError)   values the service cannot act on; each
    │   │                                  one in ``problems``                      422
    │   ├── InvalidJourneyError            a journey not valid on its line          422
    │   └── MovementAuthorityRefusedError  the RBC cannot issue or change an MA, or
    │       │                              send a TSR, as asked                     422
    │       └── EndOfAuthorityBehindVehicleError   the EoA at or behind the vehicle 409
    ├── RbcScenarioError (ValueError)      an RBC scenario script that does not load 422
    ├── RbcPublicationError                the RBC could not publish an MA or a TSR 503
    ├── VehicleTimeoutError (TimeoutError) the vehicle did not answer in time       504
    └── VehicleLinkError                   a command not sent, or its answer bad    502

The services also let trackdb's errors through (``trackdb.LineNotFoundError`` 404,
``trackdb.LineValidationError`` 422 with its problems, ``trackdb.LineConflictError`` 409); the
same handlers answer them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from trackdb.journey import JourneyCheck

__all__ = [
    "AuthenticationError",
    "ConflictError",
    "EndOfAuthorityBehindVehicleError",
    "InvalidJourneyError",
    "InvalidRequestError",
    "InvalidTokenError",
    "MovementAuthorityRefusedError",
    "NoMovementAuthorityError",
    "NotFoundError",
    "PermissionDeniedError",
    "RbcPublicationError",
    "RbcScenarioError",
    "TracksideError",
    "VehicleLinkError",
    "VehicleNotPlacedError",
    "VehicleTimeoutError",
]


class TracksideError(Exception):
    """Base of the trackside's domain errors."""


class AuthenticationError(TracksideError):
    """Credentials or token not valid."""


class InvalidTokenError(AuthenticationError):
    """A bearer token that is unknown, revoked, expired or of a deleted user.

    The message says which, for the service's own use; a client is told only that it is not
    authenticated, so that a token found or stolen reveals nothing of its state.
    """


class PermissionDeniedError(TracksideError):
    """The user's role does not allow the action."""


class NotFoundError(TracksideError, LookupError):
    """No such resource."""


class ConflictError(TracksideError):
    """The resource already exists or is held by another user."""


class InvalidRequestError(TracksideError, ValueError):
    """The request's values are well-formed but the service cannot act on them.

    ``problems`` lists what is wrong, each with its location where there is one; the message
    alone when not given.
    """

    def __init__(self, message: str, *, problems: list[str] | None = None) -> None:
        super().__init__(message)
        self.problems = [message] if problems is None else problems


class InvalidJourneyError(InvalidRequestError):
    """A journey that fails validation against the current version of its line."""

    def __init__(self, check: JourneyCheck, line_version: str) -> None:
        super().__init__("; ".join(check.problems), problems=list(check.problems))
        self.check = check
        self.line_version = line_version


class NoMovementAuthorityError(NotFoundError):
    """The RBC holds no movement authority for the vehicle (never issued, or revoked)."""


class MovementAuthorityRefusedError(InvalidRequestError):
    """The RBC cannot issue or change the movement authority as asked; nothing was sent."""


class VehicleNotPlacedError(MovementAuthorityRefusedError):
    """The RBC separates the trains on the line and no report has placed this one yet."""


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


class RbcPublicationError(TracksideError):
    """The RBC could not publish an MA or a TSR on Zenoh; nothing changed."""


class VehicleTimeoutError(TracksideError, TimeoutError):
    """The vehicle did not answer in time; what it did is unknown."""


class VehicleLinkError(TracksideError):
    """The command could not be sent, or the vehicle's answer was an error or not valid."""
