"""The Track Database Manager's transfer: the switching rule, the transfer's steps, and the
start-up fetch from a real trackside bridge over Zenoh."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
import zenoh

from onboard import TrackDataUnavailableError
from onboard.track_store import TrackDataStore
from onboard.track_transfer import (
    STANDSTILL_HOLD_S,
    TrackDataTransfer,
    fetch_line,
    switch_refusal,
)
from protocol import messages as m
from trackdb import Line, load_seed_line
from trackside.bridge import ZenohBridge

RING = load_seed_line("bologna-ring")
NEWER = RING.model_copy(update={"name": "Bologna ring, resurveyed"})


def _reply(line: Line, *, document: str | None = None) -> m.LineDocumentReply:
    text = line.model_dump_json(round_trip=True) if document is None else document
    return m.LineDocumentReply(line_id=line.id, version=line.version(), document=text)


# -- the switching rule ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("standstill_for_s", "engaged", "refused"),
    [
        (STANDSTILL_HOLD_S, False, None),
        (60.0, False, None),
        (None, False, "moving"),
        (0.0, False, "moving until"),
        (STANDSTILL_HOLD_S - 0.05, False, "moving until"),
        (60.0, True, "ATO engaged"),
        (None, True, "moving"),
    ],
)
def test_switch_only_at_standstill_held_with_ato_not_engaged(
    standstill_for_s: float | None, engaged: bool, refused: str | None
) -> None:
    refusal = switch_refusal(standstill_for_s=standstill_for_s, ato_engaged=engaged)
    if refused is None:
        assert refusal is None
    else:
        assert refusal is not None
        assert refusal.startswith(refused)


# -- the transfer ------------------------------------------------------------------------------


def test_asks_only_when_the_trackside_holds_another_version() -> None:
    transfer = TrackDataTransfer(RING.id)
    newer = NEWER.version()
    assert transfer.wanted(onboard_version=RING.version(), trackside_version=None) is None
    assert transfer.wanted(onboard_version=RING.version(), trackside_version=RING.version()) is None
    assert transfer.wanted(onboard_version=RING.version(), trackside_version=newer) == newer
    transfer.asked(newer)
    assert transfer.wanted(onboard_version=RING.version(), trackside_version=newer) is None
    transfer.retry()
    assert transfer.wanted(onboard_version=RING.version(), trackside_version=newer) == newer


def test_a_wrong_sha256_is_refused_counted_and_reported(tmp_path: Path) -> None:
    store = TrackDataStore(tmp_path)
    transfer = TrackDataTransfer(RING.id, store)
    tampered = NEWER.model_dump_json(round_trip=True).replace("resurveyed", "resurveyeD")
    transfer.on_reply(_reply(NEWER, document=tampered))
    events = transfer.take(RING.version())
    assert [e.code for e in events] == ["track_data.refused"]
    assert "SHA-256" in events[0].text
    assert transfer.refused == 1
    assert transfer.pending is None
    assert store.load(RING.id) is None
    # Asked again at the next period, as the versions still differ.
    wanted = transfer.wanted(onboard_version=RING.version(), trackside_version=NEWER.version())
    assert wanted == NEWER.version()


def test_a_verified_line_is_stored_and_waits_for_standstill(tmp_path: Path) -> None:
    store = TrackDataStore(tmp_path)
    transfer = TrackDataTransfer(RING.id, store)
    transfer.on_reply(_reply(NEWER))
    transfer.on_reply(_reply(NEWER))  # the answer to an ask repeated: taken once
    events = transfer.take(RING.version())
    assert [e.code for e in events] == ["track_data.received"]
    assert transfer.pending is not None
    assert transfer.pending.version == NEWER.version()
    stored = store.load(RING.id)
    assert stored is not None
    assert stored.version() == NEWER.version()
    pending = NEWER.version()
    assert transfer.wanted(onboard_version=RING.version(), trackside_version=pending) is None

    # Moving, then stopping: the switch waits until the standstill has lasted.
    ticks_s = [0.05 * i for i in range(200)]
    deferrals = [
        transfer.due(t, standstill=t >= 3.0, ato_engaged=t >= 3.0) for t in ticks_s if t < 9.0
    ]
    assert all(track_map is None for track_map, _ in deferrals)
    reported = [event for _, event in deferrals if event is not None]
    # Once per kind of refusal, not at each tick.
    assert [e.code for e in reported] == ["track_data.switch_deferred"] * 2
    assert "moving" in reported[0].text
    assert "ATO engaged" in reported[1].text
    # Moving again resets the standstill's clock.
    assert transfer.due(9.0, standstill=False, ato_engaged=False)[0] is None
    assert transfer.due(9.05, standstill=True, ato_engaged=False)[0] is None
    assert (
        transfer.due(9.05 + STANDSTILL_HOLD_S - 0.1, standstill=True, ato_engaged=False)[0] is None
    )

    track_map, event = transfer.due(9.05 + STANDSTILL_HOLD_S, standstill=True, ato_engaged=False)
    assert event is None
    assert track_map is not None
    assert track_map.version == NEWER.version()
    assert transfer.pending is None
    assert transfer.switches == 1


def test_replies_about_other_lines_or_the_version_in_use_change_nothing() -> None:
    transfer = TrackDataTransfer(RING.id)
    transfer.on_reply(_reply(load_seed_line("milano-bologna")))
    transfer.on_reply(_reply(RING))
    assert transfer.take(RING.version()) == []
    assert transfer.pending is None
    transfer.on_reply(m.LineDocumentReply(line_id=RING.id))
    assert [e.code for e in transfer.take(RING.version())] == ["track_data.unavailable"]


# -- the start-up fetch over Zenoh -------------------------------------------------------------


def _bridge(session: zenoh.Session, lines: dict[str, Line]) -> ZenohBridge:
    def document(line_id: str) -> tuple[str, str] | None:
        line = lines.get(line_id)
        return None if line is None else (line.model_dump_json(round_trip=True), line.version())

    return ZenohBridge(session, instance_id="ts-test", line_document=document)


@pytest.mark.parametrize(
    "copy",
    [None, RING.model_dump_json(round_trip=True), "{truncated"],
    ids=["no copy", "an old copy", "a corrupted copy"],
)
def test_fetch_gets_verifies_and_stores_the_trackside_line(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], tmp_path: Path, copy: str | None
) -> None:
    trackside, onboard = zenoh_pair
    store = TrackDataStore(tmp_path)
    if copy is not None:
        store.path(RING.id).write_text(copy)
    bridge = _bridge(trackside, {RING.id: NEWER})
    try:
        line = fetch_line(
            onboard, vehicle_id="URV1", line_id=RING.id, store=store, stop=threading.Event()
        )
    finally:
        bridge.close()
    assert line.version() == NEWER.version()
    stored = store.load(RING.id)
    assert stored is not None
    assert stored.version() == NEWER.version()


def test_fetch_waits_while_no_trackside_holds_the_line(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], tmp_path: Path
) -> None:
    trackside, onboard = zenoh_pair
    bridge = _bridge(trackside, {})
    stop = threading.Event()
    threading.Timer(0.5, stop.set).start()
    try:
        with pytest.raises(TrackDataUnavailableError, match="no trackside gave it"):
            fetch_line(
                onboard,
                vehicle_id="URV1",
                line_id="my-own-line",
                store=TrackDataStore(tmp_path),
                stop=stop,
                retry_s=0.1,
            )
    finally:
        bridge.close()


def test_pending_data_the_trackside_no_longer_holds_are_never_switched_to() -> None:
    transfer = TrackDataTransfer(RING.id)
    transfer.on_reply(_reply(NEWER))
    transfer.take(RING.version())
    assert transfer.forget_stale(None) is None  # no answer: nothing known against it
    assert transfer.forget_stale(NEWER.version()) is None
    assert transfer.pending is not None
    event = transfer.forget_stale(RING.version())  # the trackside went back
    assert event is not None
    assert event.code == "track_data.pending_dropped"
    assert transfer.pending is None
    assert transfer.due(0.0, standstill=True, ato_engaged=False) == (None, None)
