"""The VC's datalog (black box, DOMAIN.md §7.2): every notification, append-only, and its reader.

A JSON Lines file: one :class:`DatalogRecord` a line (``seq``, simulated ``time_s``,
``source``, ``kind``, ``payload``), flushed after each line, so that a crash loses at most the
line being written. :func:`read_datalog` tolerates a torn *last* line (it reports it); a bad
line anywhere else is corruption (:class:`DatalogCorruptError`).

:class:`DatalogRecorder` is the board: registered on the executive after the VC's tasks, it
records each new :class:`~onboard.vc.ipc.VcEvent` of Tasks B and C, each change of the request
notifications Task A sends, and, for a :class:`~onboard.vc.redundancy.TwoOutOfTwo`, its events.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO, Any

from onboard.runtime import Executive
from onboard.runtime.clock import NS_PER_S
from onboard.vc._exceptions import VcError
from onboard.vc.module import VitalControl
from onboard.vc.redundancy import TwoOutOfTwo

__all__ = [
    "DATALOG_PRIORITY",
    "Datalog",
    "DatalogCorruptError",
    "DatalogRecord",
    "DatalogRecorder",
    "DatalogReplay",
    "read_datalog",
]

DATALOG_PRIORITY = 5
"""Below every VC task: the recorder sees the tick's events."""

JsonObject = Mapping[str, Any]


class DatalogCorruptError(VcError, ValueError):
    """A datalog line other than the last is not a valid record."""


@dataclass(frozen=True, slots=True, kw_only=True)
class DatalogRecord:
    seq: int
    time_s: float
    source: str
    kind: str
    payload: JsonObject

    def to_json(self) -> str:
        return json.dumps(
            {
                "seq": self.seq,
                "time_s": self.time_s,
                "source": self.source,
                "kind": self.kind,
                "payload": dict(self.payload),
            },
            separators=(",", ":"),
            sort_keys=True,
            ensure_ascii=False,
        )

    @classmethod
    def from_json(cls, line: str) -> DatalogRecord:
        """Parse one line; ``ValueError`` (or ``KeyError``, ``TypeError``) if it is not one."""
        data = json.loads(line)
        if not isinstance(data, dict) or not isinstance(data["payload"], dict):
            raise ValueError("not a record object")
        return cls(
            seq=int(data["seq"]),
            time_s=float(data["time_s"]),
            source=str(data["source"]),
            kind=str(data["kind"]),
            payload=data["payload"],
        )


class Datalog:
    """An append-only JSON Lines datalog; a context manager.

    Parameters
    ----------
    path
        The file; appended to if it exists.
    fsync
        Also ``os.fsync`` after each line (slow; a flush already survives a process crash).
    """

    def __init__(self, path: Path, *, fsync: bool = False) -> None:
        self.path = path
        self.fsync = fsync
        self._file: IO[str] | None = None
        self.seq = 0

    def __enter__(self) -> Datalog:
        self.open()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def open(self) -> IO[str]:
        if self._file is None:
            self._file = self.path.open("a", encoding="utf-8")
        return self._file

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def append(
        self, time_s: float, source: str, kind: str, payload: JsonObject | None = None
    ) -> DatalogRecord:
        """Write one record and flush it."""
        file = self.open()
        record = DatalogRecord(
            seq=self.seq, time_s=time_s, source=source, kind=kind, payload=payload or {}
        )
        file.write(record.to_json() + "\n")
        file.flush()
        if self.fsync:
            os.fsync(file.fileno())
        self.seq += 1
        return record


@dataclass(frozen=True, kw_only=True)
class DatalogReplay:
    records: tuple[DatalogRecord, ...]
    torn_last_line: str | None
    """The last line's text when it was cut short (a crash while writing it)."""


def read_datalog(path: Path) -> DatalogReplay:
    """Every record of ``path``; ``FileNotFoundError`` if missing, corruption raises."""
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = text.split("\n")
    complete, last = lines[:-1], lines[-1]  # ``last`` is "" when the file ends with a newline
    records: list[DatalogRecord] = []
    torn: str | None = None
    for number, line in enumerate(complete, start=1):
        if not line.strip():
            continue
        try:
            records.append(DatalogRecord.from_json(line))
        except (ValueError, KeyError, TypeError) as exc:
            raise DatalogCorruptError(f"{path}:{number}: not a datalog record: {exc}") from exc
    if last.strip():
        # No final newline: the write was cut short. A complete record there is kept.
        try:
            records.append(DatalogRecord.from_json(last))
        except (ValueError, KeyError, TypeError):
            torn = last
    return DatalogReplay(records=tuple(records), torn_last_line=torn)


class DatalogRecorder:
    """Records a VC's (or a pair's) notifications into a :class:`Datalog` each tick."""

    def __init__(
        self, datalog: Datalog, vc: VitalControl, *, pair: TwoOutOfTwo | None = None
    ) -> None:
        self.datalog = datalog
        self.vc = vc
        self.pair = pair
        self._seen_b = self._seen_c = self._seen_pair = 0
        self._last_request_s: float | None = None
        self._last_notifications: tuple[str, ...] | None = None

    def register(self, executive: Executive, *, period_s: float = 0.002) -> None:
        executive.add_task(
            "vc.datalog",
            lambda release_ns: self.step(release_ns / NS_PER_S),
            period_s=period_s,
            priority=DATALOG_PRIORITY,
        )

    def step(self, now_s: float) -> None:  # noqa: ARG002 - records carry their own times
        """Write what is new since the last call."""
        events = self.vc.task_b.events[self._seen_b :] + self.vc.task_c.events[self._seen_c :]
        self._seen_b, self._seen_c = len(self.vc.task_b.events), len(self.vc.task_c.events)
        for event in sorted(events, key=lambda e: e.time_s):
            self.datalog.append(
                event.time_s,
                f"vc.{event.task}",
                event.kind.value,
                {"detail": event.detail, "evidence_s": event.evidence_s},
            )
        request = self.vc.task_a.last_request
        if request is not None and request.sent_s != self._last_request_s:
            self._last_request_s = request.sent_s
            notifications = tuple(n.value for n in request.notifications)
            if notifications != self._last_notifications:
                self._last_notifications = notifications
                self.datalog.append(
                    request.sent_s, "vc.A", "notifications", {"notifications": list(notifications)}
                )
        if self.pair is not None:
            for pair_event in self.pair.events[self._seen_pair :]:
                self.datalog.append(
                    pair_event.time_s,
                    "vc.2oo2",
                    pair_event.kind.value,
                    {"replica": pair_event.replica, "detail": pair_event.detail},
                )
            self._seen_pair = len(self.pair.events)
