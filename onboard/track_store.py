"""The onboard's copies of its track data on disk, and the check every copy passes.

A line document travels and is stored as its canonical JSON, the very text whose SHA-256 is the
line's version (``trackdb.Line.version``). :func:`verified_line` is the one check, used on what
the trackside sends and on what is read back from disk: the SHA-256 of the text is the version
announced, the text parses as a line of the expected id, and the line written out again is the
same text (so an edited copy that still parses is refused too).

:class:`TrackDataStore` keeps one file per line, ``DIR/{line_id}.json``. A copy is written to a
temporary file in the same directory, flushed to the disk, then renamed over the old one: a
crash leaves the old copy or the new one, never half of one. It is checked again when loaded.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import tempfile
from pathlib import Path

from onboard._exceptions import TrackDataCorruptError
from trackdb import Line, TrackDataError, parse_line

__all__ = ["TrackDataStore", "document_version", "verified_line"]

_LINE_ID = re.compile(r"[A-Za-z0-9_-]{1,64}")
"""A line id safe as a file name (the key-space chunk's characters)."""


def document_version(document: str) -> str:
    """The SHA-256 (hex) of a line document's text: its version when the text is canonical."""
    return hashlib.sha256(document.encode()).hexdigest()


def verified_line(document: str, *, line_id: str, version: str) -> Line:
    """The line of ``document``, checked to be line ``line_id`` at ``version``.

    Raises
    ------
    TrackDataCorruptError
        The SHA-256 is not ``version``, the text is not a valid line, the line is another one,
        or the text is not the line's canonical JSON.
    """
    actual = document_version(document)
    if actual != version:
        raise TrackDataCorruptError(
            f"line {line_id}: SHA-256 {actual[:12]}… is not the version {version[:12]}…"
        )
    try:
        line = parse_line(document)
    except (TrackDataError, ValueError) as exc:
        raise TrackDataCorruptError(f"line {line_id}: not a valid line document: {exc}") from exc
    if line.id != line_id:
        raise TrackDataCorruptError(f"line {line_id}: the document is line {line.id}")
    if line.version() != version:
        raise TrackDataCorruptError(f"line {line_id}: the document is not in canonical form")
    return line


class TrackDataStore:
    """Verified line documents in one directory, one file per line.

    Parameters
    ----------
    directory : Path
        Where the copies are kept (made on the first save).
    """

    def __init__(self, directory: Path) -> None:
        self.directory = directory

    def path(self, line_id: str) -> Path:
        """The file of line ``line_id``'s copy; ValueError for an id unfit for a file name."""
        if not _LINE_ID.fullmatch(line_id):
            raise ValueError(f"line id {line_id!r} is not a valid line id")
        return self.directory / f"{line_id}.json"

    def save(self, document: str, *, line_id: str, version: str) -> Line:
        """Check ``document`` (:func:`verified_line`), then write it atomically; the line.

        Raises
        ------
        TrackDataCorruptError
            The document fails its check: nothing is written.
        OSError
            The directory or the file cannot be written: the old copy, if any, stays.
        """
        line = verified_line(document, line_id=line_id, version=version)
        target = self.path(line_id)
        self.directory.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(
            prefix=f".{line_id}.", suffix=".tmp", dir=self.directory
        )
        try:
            with os.fdopen(handle, "wb") as out:
                out.write(document.encode())
                out.flush()
                os.fsync(out.fileno())
            os.replace(temporary, target)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(temporary)
            raise
        _sync_directory(self.directory)
        return line

    def load(self, line_id: str) -> Line | None:
        """The stored copy of line ``line_id``, checked again; None when there is none.

        Raises
        ------
        TrackDataCorruptError
            The copy on disk is not a line document of that id in canonical form (truncated,
            edited, another line's): it is not used.
        """
        path = self.path(line_id)
        try:
            document = path.read_bytes().decode()
        except FileNotFoundError:
            return None
        except (OSError, UnicodeDecodeError) as exc:
            raise TrackDataCorruptError(f"line {line_id}: {path} unreadable: {exc}") from exc
        return verified_line(document, line_id=line_id, version=document_version(document))


def _sync_directory(directory: Path) -> None:
    """Make the rename durable (POSIX: the directory's entry is flushed with the directory)."""
    try:
        descriptor = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(descriptor)
    except OSError:
        pass
    finally:
        os.close(descriptor)
