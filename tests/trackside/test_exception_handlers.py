"""The HTTP answer of each domain error, given in one place by the app's exception handlers."""

from __future__ import annotations

import inspect
from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from trackdb import LineConflictError, LineNotFoundError, LineValidationError
from trackdb.journey import JourneyCheck, LegCheck
from trackside import errors
from trackside.api.exception_handlers import ERROR_ANSWERS, add_exception_handlers

CHECK = JourneyCheck(
    problems=("east: 60 s scheduled, 80 s needed",),
    legs=(
        LegCheck(
            index=0,
            from_id="start",
            to_id="east",
            distance_m=400.0,
            scheduled_s=60.0,
            minimum_s=80.0,
        ),
    ),
    positions_m=(400.0,),
    distances_m=(400.0,),
)
CASES: list[tuple[Exception, int, Any]] = [
    (errors.AuthenticationError("wrong username or password"), 401, "wrong username or password"),
    (errors.InvalidTokenError("token expired"), 401, "not authenticated"),
    (errors.PermissionDeniedError("admin role needed"), 403, "admin role needed"),
    (errors.NotFoundError("no journey 'x'"), 404, "no journey 'x'"),
    (errors.NoMovementAuthorityError("no MA for URV1"), 404, "no MA for URV1"),
    (LineNotFoundError("ring"), 404, "no line 'ring'"),
    (errors.ConflictError("URV1 is held by alice"), 409, "URV1 is held by alice"),
    (LineConflictError("raced"), 409, "raced"),
    (
        errors.EndOfAuthorityBehindVehicleError("behind", end_of_authority_m=1.0, position_m=2.0),
        409,
        {"message": "behind", "problems": ["behind"]},
    ),
    (
        errors.InvalidRequestError("step 0 m"),
        422,
        {"message": "step 0 m", "problems": ["step 0 m"]},
    ),
    (
        errors.MovementAuthorityRefusedError("not a speed restriction", problems=["end_m > 0"]),
        422,
        {"message": "not a speed restriction", "problems": ["end_m > 0"]},
    ),
    (
        LineValidationError("ring", ["a", "b"]),
        422,
        {"message": "line 'ring': a; b", "problems": ["a", "b"]},
    ),
    (errors.RbcScenarioError("bad", ["x", "y"]), 422, {"message": "bad", "problems": ["x", "y"]}),
    (
        errors.InvalidJourneyError(CHECK, "v1"),
        422,
        {
            "message": "journey not valid on its line",
            "valid": False,
            "problems": list(CHECK.problems),
            "legs": [
                {
                    "index": 0,
                    "from_id": "start",
                    "to_id": "east",
                    "distance_m": 400.0,
                    "scheduled_s": 60.0,
                    "minimum_s": 80.0,
                    "shortfall_s": 20.0,
                }
            ],
            "line_version": "v1",
        },
    ),
    (errors.VehicleLinkError("URV1: bad answer"), 502, "URV1: bad answer"),
    (errors.RbcPublicationError("not published"), 503, "not published"),
    (errors.VehicleTimeoutError("URV1 did not answer"), 504, "URV1 did not answer"),
]


def _raising(error: Exception) -> TestClient:
    app = FastAPI()
    add_exception_handlers(app)

    @app.get("/raise")
    def raise_it() -> None:
        raise error

    return TestClient(app)


@pytest.mark.parametrize(
    ("error", "status_code", "detail"), CASES, ids=[type(case[0]).__name__ for case in CASES]
)
def test_each_error_is_answered_with_its_status_and_detail(
    error: Exception, status_code: int, detail: Any
) -> None:
    response = _raising(error).get("/raise")
    assert response.status_code == status_code
    assert response.json() == {"detail": detail}
    bearer = response.headers.get("WWW-Authenticate")
    assert bearer == ("Bearer" if status_code == 401 else None)


def test_every_domain_error_has_an_answer() -> None:
    """A new error class cannot be forgotten: it, or a base of it, is answered."""
    classes = [
        item
        for name in errors.__all__
        if inspect.isclass(item := getattr(errors, name)) and item is not errors.TracksideError
    ]
    unanswered = [c.__name__ for c in classes if not set(c.__mro__) & set(ERROR_ANSWERS)]
    assert unanswered == []


def test_an_error_without_an_answer_stays_a_server_error() -> None:
    client = _raising(errors.TracksideError("a bug"))
    with pytest.raises(errors.TracksideError):
        client.get("/raise")
