"""Line storage on SQLite and PostgreSQL: import, export, versions, atomic rejection."""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from typing import Any

import pytest
from sqlalchemy import Engine, create_engine, event, func, select
from sqlalchemy.orm import Session

from tests.trackdb.layouts import small_ring, tiny_line
from trackdb import (
    SEED_LINES,
    LineConflictError,
    LineNotFoundError,
    LineValidationError,
    TrackDataError,
    load_seed_line,
    storage,
)
from trackdb.storage import LineRow, LineVersionRow


@pytest.fixture
def engine(database_url: str) -> Iterator[Engine]:
    engine = create_engine(database_url)
    if engine.dialect.name == "sqlite":

        @event.listens_for(engine, "connect")
        def _foreign_keys(dbapi_connection: Any, _record: Any) -> None:
            dbapi_connection.execute("PRAGMA foreign_keys=ON")

    storage.metadata.create_all(engine)
    yield engine
    engine.dispose()


@pytest.fixture
def session(engine: Engine) -> Iterator[Session]:
    with Session(engine) as session:
        yield session


def _counts(session: Session) -> tuple[int, int]:
    return (
        session.scalar(select(func.count()).select_from(LineVersionRow)) or 0,
        session.scalar(select(func.count()).select_from(LineRow)) or 0,
    )


@pytest.mark.parametrize("line_id", sorted(SEED_LINES))
def test_seed_line_import_export_reimport_keeps_the_version(line_id: str, engine: Engine) -> None:
    seed = load_seed_line(line_id)
    with Session(engine) as session, session.begin():
        stored = storage.import_line(session, seed)
    assert stored == seed
    assert stored.version() == seed.version()
    with Session(engine) as session:
        exported = storage.export_line(session, line_id)
        assert storage.get_line(session, line_id) == seed
    assert hashlib.sha256(exported.encode()).hexdigest() == seed.version()
    with Session(engine) as session, session.begin():
        again = storage.import_line(session, exported)
        assert again.version() == seed.version()
        assert _counts(session) == (1, 1)
        [summary] = storage.line_versions(session, line_id)
    assert summary.current
    assert summary.version == seed.version()


def test_reimport_is_a_no_op(session: Session) -> None:
    storage.import_line(session, tiny_line())
    session.commit()
    before = storage.line_versions(session, "tiny")
    storage.import_line(session, tiny_line().model_dump(mode="json"))
    session.commit()
    assert storage.line_versions(session, "tiny") == before
    assert _counts(session) == (1, 1)


@pytest.mark.parametrize(
    "as_document",
    [
        lambda line: line,
        lambda line: line.model_dump(mode="json"),
        lambda line: line.model_dump_json(),
        lambda line: line.model_dump_json().encode(),
        lambda line: line.model_dump(mode="json", exclude={"schema_version", "etcs_level"}),
    ],
    ids=["line", "mapping", "text", "bytes", "without-defaults"],
)
def test_every_form_of_a_document_gives_the_same_version(
    session: Session, as_document: Any
) -> None:
    line = small_ring()
    assert storage.import_line(session, as_document(line)).version() == line.version()
    assert storage.current_version(session, "small-ring") == line.version()
    assert storage.export_line(session, "small-ring") == line.model_dump_json(round_trip=True)


def test_versions_are_kept_and_the_latest_import_is_current(session: Session) -> None:
    first, second = tiny_line(), tiny_line(name="Tiny line, renamed", tsr_speed_kmh=20.0)
    storage.import_line(session, first)
    storage.import_line(session, second)
    storage.import_line(session, small_ring())
    session.commit()
    versions = storage.line_versions(session, "tiny")
    assert [v.version for v in versions] == [first.version(), second.version()]
    assert [v.current for v in versions] == [False, True]
    assert versions[0].created_at.tzinfo is not None
    assert storage.get_line(session, "tiny") == second
    assert storage.get_line(session, "tiny", first.version()) == first
    summaries = storage.list_lines(session)
    assert [(s.id, s.name, s.current) for s in summaries] == [
        ("small-ring", "Small ring", True),
        ("tiny", "Tiny line, renamed", True),
    ]
    assert summaries[1].length_m == 1000.0
    assert not summaries[1].ring
    # Importing an older version again makes it current without storing it twice.
    storage.import_line(session, first)
    session.commit()
    assert storage.current_version(session, "tiny") == first.version()
    assert _counts(session) == (3, 2)


@pytest.mark.parametrize(
    ("breakage", "expected"),
    [
        ({"speed": -1.0, "stop": 5000.0}, ["non-positive speed", "beyond the line's end"]),
        ({"colour": "blue", "length": "long"}, ["balise_groups.0.colour", "length_m"]),
    ],
    ids=["line-rules", "fields"],
)
def test_an_invalid_line_is_rejected_whole(
    session: Session, breakage: dict[str, Any], expected: list[str]
) -> None:
    document = tiny_line().model_dump(mode="json")
    if "speed" in breakage:
        document["speed_limit_mps"][0]["value"] = breakage["speed"]
        document["stopping_points"][0]["position_m"] = breakage["stop"]
    else:
        document["balise_groups"][0]["colour"] = breakage["colour"]
        document["length_m"] = breakage["length"]
    with pytest.raises(LineValidationError) as caught:
        storage.import_line(session, document)
    problems = caught.value.problems
    for fragment in expected:
        assert any(fragment in problem for problem in problems), problems
    assert caught.value.line_id == "tiny"
    assert not session.new
    assert not session.dirty
    session.commit()
    assert _counts(session) == (0, 0)


def test_a_rejected_version_leaves_the_current_one(session: Session) -> None:
    storage.import_line(session, tiny_line())
    session.commit()
    broken = tiny_line(name="Broken").model_dump(mode="json") | {"length_m": -5.0}
    with pytest.raises(LineValidationError):
        storage.import_line(session, broken)
    session.commit()
    assert storage.current_version(session, "tiny") == tiny_line().version()
    assert _counts(session) == (1, 1)


def test_not_json_is_a_validation_error(session: Session) -> None:
    with pytest.raises(LineValidationError) as caught:
        storage.import_line(session, b"{not json")
    assert caught.value.problems
    assert "JSON" in caught.value.problems[0]


def test_unknown_line_or_version_raises(session: Session) -> None:
    storage.import_line(session, tiny_line())
    for call in (
        lambda: storage.get_line(session, "nowhere"),
        lambda: storage.export_line(session, "nowhere"),
        lambda: storage.current_version(session, "nowhere"),
        lambda: storage.line_versions(session, "nowhere"),
    ):
        with pytest.raises(LineNotFoundError) as caught:
            call()
        assert caught.value.line_id == "nowhere"
        assert caught.value.version is None
    with pytest.raises(LineNotFoundError) as caught:
        storage.get_line(session, "tiny", "0" * 64)
    assert caught.value.version == "0" * 64
    assert isinstance(caught.value, LookupError)
    assert isinstance(caught.value, TrackDataError)
    assert storage.list_lines(session)[0].id == "tiny"


def test_a_lost_race_is_a_conflict(session: Session, monkeypatch: pytest.MonkeyPatch) -> None:
    storage.import_line(session, tiny_line())
    session.commit()
    # As if another session had stored this version between the check and the insert.
    monkeypatch.setattr(storage, "_version_row", lambda *_args: None)
    with pytest.raises(LineConflictError):
        storage.import_line(session, tiny_line())
    session.rollback()
    assert _counts(session) == (1, 1)
