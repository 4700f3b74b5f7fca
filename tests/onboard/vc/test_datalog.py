"""The VC datalog: record → replay round trip, a torn last line, corruption, the recorder."""

from __future__ import annotations

from pathlib import Path

import pytest

from deploy.bench.vc_responder import AtoObResponder, ResponderFault, ResponderFaultKind
from onboard.runtime import Executive, SimClock
from onboard.vc import VcHardware, VitalControl
from onboard.vc.datalog import (
    Datalog,
    DatalogCorruptError,
    DatalogRecorder,
    read_datalog,
)


def test_records_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "vc.jsonl"
    with Datalog(path) as datalog:
        written = [
            datalog.append(0.002, "vc.B", "eb_condition", {"detail": "2", "evidence_s": 0.001}),
            datalog.append(0.004, "vc.C", "eb_commanded", {"detail": "valves"}),
            datalog.append(0.040, "vc.A", "notifications", {"notifications": ["eb_applied"]}),
        ]
    replay = read_datalog(path)
    assert replay.records == tuple(written)
    assert replay.torn_last_line is None
    assert [r.seq for r in replay.records] == [0, 1, 2]


def test_a_torn_last_line_is_tolerated_and_reported(tmp_path: Path) -> None:
    path = tmp_path / "vc.jsonl"
    with Datalog(path) as datalog:
        datalog.append(1.0, "vc.B", "eb_condition", {"detail": "1"})
    with path.open("a", encoding="utf-8") as file:
        file.write('{"seq":1,"time_s":1.002,"sour')  # the crash cut the write short
    replay = read_datalog(path)
    assert len(replay.records) == 1
    assert replay.torn_last_line == '{"seq":1,"time_s":1.002,"sour'


def test_a_bad_line_before_the_last_is_corruption(tmp_path: Path) -> None:
    path = tmp_path / "vc.jsonl"
    path.write_text('not json\n{"seq":0}\n', encoding="utf-8")
    with pytest.raises(DatalogCorruptError, match=":1:"):
        read_datalog(path)


def test_the_recorder_logs_every_event_of_a_run(tmp_path: Path) -> None:
    hardware = VcHardware.emulated()
    vc = VitalControl(hardware)
    executive = Executive(SimClock())
    vc.register(executive)
    fail = ResponderFault(kind=ResponderFaultKind.STATUS_FAIL, start_s=0.5)
    responder = AtoObResponder(hardware.request_link, hardware.response_link, faults=(fail,))
    executive.add_task("ato_ob", responder.step_ns, period_s=0.002, priority=0)
    path = tmp_path / "vc.jsonl"
    with Datalog(path) as datalog:
        DatalogRecorder(datalog, vc).register(executive)
        executive.run_for(1.0)
    records = read_datalog(path).records
    events = [r for r in records if r.source in ("vc.B", "vc.C")]
    assert [(r.time_s, r.kind) for r in events] == [(e.time_s, e.kind.value) for e in vc.events]
    assert any(r.kind == "system_decay" for r in records)
    assert any(r.kind == "notifications" for r in records)
    times = [r.time_s for r in records]
    assert times == sorted(times)
