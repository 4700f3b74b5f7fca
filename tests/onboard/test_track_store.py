"""The onboard's store of track data: verified, atomic writes; copies checked again on load."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from onboard import TrackDataCorruptError
from onboard.track_store import TrackDataStore, document_version, verified_line
from trackdb import Line, load_seed_line

RING = load_seed_line("bologna-ring")
DOCUMENT = RING.model_dump_json(round_trip=True)
VERSION = RING.version()


def _renamed(line: Line, name: str) -> Line:
    return line.model_copy(update={"name": name})


def test_the_version_is_the_sha256_of_the_canonical_document() -> None:
    assert document_version(DOCUMENT) == VERSION
    assert verified_line(DOCUMENT, line_id=RING.id, version=VERSION) == RING


@pytest.mark.parametrize(
    ("document", "line_id", "version", "reason"),
    [
        (DOCUMENT, RING.id, "0" * 64, "is not the version"),
        (DOCUMENT[:-1], RING.id, document_version(DOCUMENT[:-1]), "not a valid line"),
        (DOCUMENT, "milano-bologna", VERSION, "the document is line bologna-ring"),
        (DOCUMENT + " ", RING.id, document_version(DOCUMENT + " "), "canonical form"),
    ],
)
def test_a_document_that_is_not_what_it_claims_is_refused(
    document: str, line_id: str, version: str, reason: str
) -> None:
    with pytest.raises(TrackDataCorruptError, match=reason):
        verified_line(document, line_id=line_id, version=version)


def test_save_then_load_gives_the_same_line(tmp_path: Path) -> None:
    store = TrackDataStore(tmp_path / "track")
    assert store.load(RING.id) is None
    assert store.save(DOCUMENT, line_id=RING.id, version=VERSION) == RING
    assert store.path(RING.id).read_text() == DOCUMENT
    loaded = store.load(RING.id)
    assert loaded is not None
    assert loaded.version() == VERSION
    assert os.listdir(tmp_path / "track") == [f"{RING.id}.json"]


def test_a_newer_version_replaces_the_copy(tmp_path: Path) -> None:
    store = TrackDataStore(tmp_path)
    store.save(DOCUMENT, line_id=RING.id, version=VERSION)
    newer = _renamed(RING, "Bologna ring, resurveyed")
    store.save(newer.model_dump_json(round_trip=True), line_id=RING.id, version=newer.version())
    loaded = store.load(RING.id)
    assert loaded is not None
    assert loaded.version() == newer.version()


def test_a_refused_document_writes_nothing(tmp_path: Path) -> None:
    store = TrackDataStore(tmp_path)
    store.save(DOCUMENT, line_id=RING.id, version=VERSION)
    tampered = DOCUMENT.replace("Bologna", "Bolognx", 1)
    with pytest.raises(TrackDataCorruptError):
        store.save(tampered, line_id=RING.id, version=VERSION)
    assert store.path(RING.id).read_text() == DOCUMENT
    assert os.listdir(tmp_path) == [f"{RING.id}.json"]


def test_a_write_that_fails_midway_leaves_the_old_copy_and_no_debris(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    store = TrackDataStore(tmp_path)
    store.save(DOCUMENT, line_id=RING.id, version=VERSION)
    newer = _renamed(RING, "Bologna ring, resurveyed")

    def crash(_source: object, _target: object) -> None:
        raise OSError("disk pulled out")

    monkeypatch.setattr(os, "replace", crash)
    with pytest.raises(OSError, match="disk pulled out"):
        store.save(newer.model_dump_json(round_trip=True), line_id=RING.id, version=newer.version())
    monkeypatch.undo()
    assert store.path(RING.id).read_text() == DOCUMENT
    assert os.listdir(tmp_path) == [f"{RING.id}.json"]


@pytest.mark.parametrize(
    ("damage", "reason"),
    [
        (lambda text: text[: len(text) // 2], "not a valid line"),
        (lambda text: text.replace('"name":', '"name" :', 1), "canonical form"),
        (lambda _text: "\udcff", "unreadable"),
        (
            lambda _text: load_seed_line("milano-bologna").model_dump_json(round_trip=True),
            "the document is line milano-bologna",
        ),
    ],
)
def test_a_corrupted_copy_on_disk_is_refused_when_loaded(
    tmp_path: Path, damage: object, reason: str
) -> None:
    store = TrackDataStore(tmp_path)
    store.save(DOCUMENT, line_id=RING.id, version=VERSION)
    assert callable(damage)
    text = damage(DOCUMENT)
    store.path(RING.id).write_bytes(text.encode(errors="surrogateescape"))
    with pytest.raises(TrackDataCorruptError, match=reason):
        store.load(RING.id)


def test_a_line_id_unfit_for_a_file_name_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="not a valid line id"):
        TrackDataStore(tmp_path).path("../etc/passwd")
