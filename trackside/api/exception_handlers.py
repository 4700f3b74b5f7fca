"""The HTTP answer to each domain error: the one place where errors become status codes.

The services raise :mod:`trackside.errors` (and let trackdb's through) and know nothing of HTTP;
the routes let them propagate; :func:`add_exception_handlers`, called by ``create_app``,
answers each with its status code and a ``{"detail": ...}`` body, as FastAPI's own
``HTTPException`` would. Starlette picks the handler of the first class in the error's MRO that
has one, so a subclass listed in :data:`ERROR_ANSWERS` overrides its base (an EoA behind the
vehicle is a refused MA, yet 409, not 422). An error not listed stays a 500.

=================================================  ======  =====================================
error                                              status  ``detail``
=================================================  ======  =====================================
``AuthenticationError`` (bad credentials)          401     its message; ``WWW-Authenticate``
``InvalidTokenError``                              401     ``"not authenticated"``
``PermissionDeniedError``                          403     its message
``NotFoundError``, ``trackdb.LineNotFoundError``   404     its message
``ConflictError``, ``trackdb.LineConflictError``   409     its message
``EndOfAuthorityBehindVehicleError``               409     ``ProblemsPublic``
``InvalidRequestError`` (MA or TSR refused, ...)   422     ``ProblemsPublic``
``trackdb.LineValidationError``, RBC scenario      422     ``ProblemsPublic``
``InvalidJourneyError``                            422     the message and the journey's check
``VehicleLinkError``                               502     its message
``RbcPublicationError``                            503     its message
``VehicleTimeoutError``                            504     its message
=================================================  ======  =====================================
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass
from typing import Any

from fastapi import FastAPI, Request, Response, status
from fastapi.responses import JSONResponse

from trackdb import LineConflictError, LineNotFoundError, LineValidationError
from trackside.api.schemas import JourneyCheckPublic, ProblemsPublic
from trackside.errors import (
    AuthenticationError,
    ConflictError,
    EndOfAuthorityBehindVehicleError,
    InvalidJourneyError,
    InvalidRequestError,
    InvalidTokenError,
    NotFoundError,
    PermissionDeniedError,
    RbcPublicationError,
    RbcScenarioError,
    VehicleLinkError,
    VehicleTimeoutError,
)

__all__ = ["ERROR_ANSWERS", "ErrorAnswer", "add_exception_handlers"]

BEARER = {"WWW-Authenticate": "Bearer"}


def _message(exc: Exception) -> str:
    return str(exc)


def _not_authenticated(_exc: InvalidTokenError) -> str:
    return "not authenticated"


def _problems(exc: InvalidRequestError | LineValidationError | RbcScenarioError) -> dict[str, Any]:
    return ProblemsPublic(message=str(exc), problems=exc.problems).model_dump(mode="json")


def _journey_refused(exc: InvalidJourneyError) -> dict[str, Any]:
    check = JourneyCheckPublic.from_check(exc.check, exc.line_version)
    return {"message": "journey not valid on its line"} | check.model_dump(mode="json")


@dataclass(frozen=True, kw_only=True)
class ErrorAnswer:
    """How one error class is answered."""

    status_code: int
    detail: Callable[[Any], object] = _message
    """The body's ``detail``, from the error (of the class it answers, or a subclass)."""
    headers: Mapping[str, str] | None = None


ERROR_ANSWERS: dict[type[Exception], ErrorAnswer] = {
    AuthenticationError: ErrorAnswer(status_code=status.HTTP_401_UNAUTHORIZED, headers=BEARER),
    # A client learns only that its token does not do, not whether it expired or was revoked.
    InvalidTokenError: ErrorAnswer(
        status_code=status.HTTP_401_UNAUTHORIZED, detail=_not_authenticated, headers=BEARER
    ),
    PermissionDeniedError: ErrorAnswer(status_code=status.HTTP_403_FORBIDDEN),
    NotFoundError: ErrorAnswer(status_code=status.HTTP_404_NOT_FOUND),
    LineNotFoundError: ErrorAnswer(status_code=status.HTTP_404_NOT_FOUND),
    ConflictError: ErrorAnswer(status_code=status.HTTP_409_CONFLICT),
    LineConflictError: ErrorAnswer(status_code=status.HTTP_409_CONFLICT),
    EndOfAuthorityBehindVehicleError: ErrorAnswer(
        status_code=status.HTTP_409_CONFLICT, detail=_problems
    ),
    InvalidRequestError: ErrorAnswer(
        status_code=status.HTTP_422_UNPROCESSABLE_CONTENT, detail=_problems
    ),
    InvalidJourneyError: ErrorAnswer(
        status_code=status.HTTP_422_UNPROCESSABLE_CONTENT, detail=_journey_refused
    ),
    LineValidationError: ErrorAnswer(
        status_code=status.HTTP_422_UNPROCESSABLE_CONTENT, detail=_problems
    ),
    RbcScenarioError: ErrorAnswer(
        status_code=status.HTTP_422_UNPROCESSABLE_CONTENT, detail=_problems
    ),
    VehicleLinkError: ErrorAnswer(status_code=status.HTTP_502_BAD_GATEWAY),
    RbcPublicationError: ErrorAnswer(status_code=status.HTTP_503_SERVICE_UNAVAILABLE),
    VehicleTimeoutError: ErrorAnswer(status_code=status.HTTP_504_GATEWAY_TIMEOUT),
}
"""Each error class answered, with its status code, ``detail`` and headers."""


def _handler(answer: ErrorAnswer) -> Callable[[Request, Exception], Awaitable[Response]]:
    # async: Starlette would run a plain function in a worker thread, for nothing.
    async def respond(_request: Request, exc: Exception) -> Response:
        return JSONResponse(
            {"detail": answer.detail(exc)},
            status_code=answer.status_code,
            headers=None if answer.headers is None else dict(answer.headers),
        )

    return respond


def add_exception_handlers(app: FastAPI) -> None:
    """Answer every error of :data:`ERROR_ANSWERS` raised by a route or a dependency."""
    for error, answer in ERROR_ANSWERS.items():
        app.add_exception_handler(error, _handler(answer))
