"""The RBC emulator on its own: issue, extend, shorten, revoke, and what it refuses."""

from __future__ import annotations

from typing import Any

import pytest

from protocol import TransportError, ZenohSettings, open_session
from protocol import messages as m
from tests.trackside.reports import status_report
from trackside.errors import (
    EndOfAuthorityBehindVehicleError,
    MovementAuthorityRefusedError,
    NoMovementAuthorityError,
    RbcPublicationError,
)
from trackside.rbc import LineInfo, MovementAuthorityIssue, RbcEmulator

OPEN = LineInfo(version="open-v1", length_m=10_000.0, ring=False)
RING = LineInfo(version="ring-v1", length_m=5_700.0, ring=True)
LINES = {"open": OPEN, "ring": RING}
Change = m.MovementAuthorityChange


class Clock:
    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


def _status(line_id: str, position_m: float) -> m.StatusReport:
    return status_report("URV1", position_m, line_id=line_id, confidence_m=None)


class Positions:
    def __init__(self) -> None:
        self.reports: dict[str, m.StatusReport] = {}

    def __call__(self, vehicle_id: str) -> m.StatusReport | None:
        return self.reports.get(vehicle_id)


def _issue(line_id: str = "open", **fields: Any) -> MovementAuthorityIssue:
    values: dict[str, Any] = {"line_id": line_id, "start_m": 100.0, "end_of_authority_m": 900.0}
    return MovementAuthorityIssue.model_validate(values | fields)


@pytest.fixture
def positions() -> Positions:
    return Positions()


@pytest.fixture
def rbc(positions: Positions) -> RbcEmulator:
    return RbcEmulator(clock=Clock(), line_info=LINES.get, positions=positions)


def test_issue_extend_shorten_revoke_numbered_in_order(rbc: RbcEmulator) -> None:
    heard: list[m.MovementAuthorityMessage] = []
    rbc.add_listener(heard.append)
    clock = rbc.clock
    assert isinstance(clock, Clock)
    issued = rbc.issue("URV1", _issue(overlap_m=50.0, release_speed_mps=4.0))
    clock.now_s = 10.0
    extended = rbc.extend("URV1", m.MovementAuthorityEnd(end_of_authority_m=1500.0))
    clock.now_s = 20.0
    shortened = rbc.shorten("URV1", 1200.0)
    assert rbc.current("URV1") == shortened
    revoked = rbc.revoke("URV1")
    assert heard == [issued, extended, shortened, revoked]
    assert [msg.ma_id for msg in heard] == [1, 2, 3, 4]
    assert [msg.change for msg in heard] == [
        Change.ISSUED,
        Change.EXTENDED,
        Change.SHORTENED,
        Change.REVOKED,
    ]
    assert [msg.issued_at_s for msg in heard] == [0.0, 10.0, 20.0, 20.0]
    assert {msg.line_version for msg in heard} == {"open-v1"}
    assert issued.authority is not None
    assert issued.authority.supervised_location_m == 950.0
    # The end's overlap and release speed belong to the old EoA: the extension drops them.
    assert extended.authority is not None
    assert (extended.authority.start_m, extended.authority.overlap_m) == (100.0, 0.0)
    assert extended.authority.release_speed_mps is None
    assert revoked.authority is None
    assert rbc.current("URV1") is None
    assert rbc.last_ma_id("URV1") == 4
    # Numbering goes on after a revocation.
    assert rbc.issue("URV1", _issue()).ma_id == 5
    assert rbc.vehicle_ids() == ["URV1"]


def test_extension_appends_a_section_and_shortening_cuts_them(rbc: RbcEmulator) -> None:
    sections = [{"length_m": 300.0, "timer_s": 60.0, "timer_stop_m": 250.0}, {"length_m": 500.0}]
    rbc.issue("URV1", _issue(sections=sections))
    extended = rbc.extend("URV1", 1200.0).authority
    assert extended is not None
    assert [s.length_m for s in extended.sections] == [300.0, 500.0, 300.0]
    shortened = rbc.shorten("URV1", 300.0).authority
    assert shortened is not None
    assert [(s.length_m, s.timer_stop_m) for s in shortened.sections] == [(200.0, 200.0)]


@pytest.mark.parametrize(
    ("operation", "end_m", "needle"),
    [
        ("extend", 900.0, "must move the EoA forward"),
        ("extend", 20_000.0, "leaves line open"),
        ("shorten", 900.0, "must move the EoA back"),
        ("shorten", 100.0, "beyond the MA's start"),
    ],
)
def test_changes_that_go_the_wrong_way_are_refused_and_change_nothing(
    rbc: RbcEmulator, operation: str, end_m: float, needle: str
) -> None:
    before = rbc.issue("URV1", _issue())
    with pytest.raises(MovementAuthorityRefusedError, match=needle):
        getattr(rbc, operation)("URV1", end_m)
    assert rbc.current("URV1") == before
    assert rbc.last_ma_id("URV1") == 1


def test_no_authority_to_change(rbc: RbcEmulator) -> None:
    for change in (lambda: rbc.extend("URV1", 2000.0), lambda: rbc.revoke("URV1")):
        with pytest.raises(NoMovementAuthorityError):
            change()
    with pytest.raises(NoMovementAuthorityError):
        rbc.shorten("URV1", 500.0)


@pytest.mark.parametrize(
    ("fields", "needle"),
    [
        ({"line_id": "nowhere"}, "holds no line 'nowhere'"),
        ({"line_version": "old"}, "is at version open-v1, not old"),
        ({"start_m": -5.0}, "leaves line open"),
        ({"end_of_authority_m": 9_990.0, "overlap_m": 50.0}, "SvL at 10040 m leaves"),
        ({"line_id": "ring", "start_m": 6_000.0, "end_of_authority_m": 6_500.0}, "not a chainage"),
        ({"line_id": "ring", "end_of_authority_m": 5_800.0}, "less than one lap"),
    ],
)
def test_issues_off_the_line_are_refused(
    rbc: RbcEmulator, fields: dict[str, Any], needle: str
) -> None:
    with pytest.raises(MovementAuthorityRefusedError, match=needle):
        rbc.issue("URV1", _issue(**fields))
    assert rbc.current("URV1") is None
    assert rbc.last_ma_id("URV1") == 0


def test_bad_vehicle_id_is_refused(rbc: RbcEmulator) -> None:
    with pytest.raises(MovementAuthorityRefusedError, match="bad vehicle id"):
        rbc.issue("a/b", _issue())


def test_without_a_line_lookup_the_version_must_be_given() -> None:
    rbc = RbcEmulator(clock=Clock())
    with pytest.raises(MovementAuthorityRefusedError, match="give line_version"):
        rbc.issue("URV1", _issue())
    assert rbc.issue("URV1", _issue(line_version="given")).line_version == "given"


def test_eoa_at_or_behind_the_reported_front_end_is_refused(
    rbc: RbcEmulator, positions: Positions
) -> None:
    rbc.issue("URV1", _issue(end_of_authority_m=2000.0))
    positions.reports["URV1"] = _status("open", 1200.0)
    with pytest.raises(EndOfAuthorityBehindVehicleError, match="last reported at 1200 m") as caught:
        rbc.shorten("URV1", 1200.0)
    assert (caught.value.end_of_authority_m, caught.value.position_m) == (1200.0, 1200.0)
    assert rbc.shorten("URV1", 1200.5).ma_id == 2
    with pytest.raises(EndOfAuthorityBehindVehicleError):
        rbc.issue("URV1", _issue(end_of_authority_m=1100.0))
    # A report from another line says nothing about this MA.
    positions.reports["URV1"] = _status("ring", 1500.0)
    assert rbc.shorten("URV1", 1100.0).ma_id == 3


def test_margin_ahead_of_the_vehicle() -> None:
    positions = Positions()
    rbc = RbcEmulator(clock=Clock(), line_info=LINES.get, positions=positions, margin_m=50.0)
    rbc.issue("URV1", _issue(end_of_authority_m=2000.0))
    positions.reports["URV1"] = _status("open", 1000.0)
    with pytest.raises(EndOfAuthorityBehindVehicleError, match="plus the 50 m margin"):
        rbc.shorten("URV1", 1040.0)
    assert rbc.shorten("URV1", 1060.0).ma_id == 2


def test_positions_on_a_ring_are_unwrapped_near_the_authority(
    rbc: RbcEmulator, positions: Positions
) -> None:
    # From 5000 m over the origin: the EoA at 6200 m is chainage 500 m of the next lap.
    rbc.issue("URV1", _issue("ring", start_m=5000.0, end_of_authority_m=6200.0))
    positions.reports["URV1"] = _status("ring", 300.0)  # 6000 m unwrapped
    with pytest.raises(EndOfAuthorityBehindVehicleError):
        rbc.shorten("URV1", 5900.0)
    assert rbc.shorten("URV1", 6100.0).ma_id == 2
    # A vehicle a little behind the start is behind it, not a lap ahead.
    positions.reports["URV1"] = _status("ring", 4990.0)
    assert rbc.shorten("URV1", 5010.0).ma_id == 3


def test_a_failed_publication_changes_nothing() -> None:
    with open_session(ZenohSettings(mode="peer", connect=())) as session:
        rbc = RbcEmulator(clock=Clock(), session=session)
    # The session is closed now: declaring the vehicle's publisher fails, and the RBC says so
    # with an error of its own.
    with pytest.raises(RbcPublicationError, match="nothing changed") as raised:
        rbc.issue("URV1", _issue(line_version="v"))
    assert isinstance(raised.value.__cause__, TransportError)
    assert rbc.current("URV1") is None
    assert rbc.last_ma_id("URV1") == 0
    rbc.close()


def test_a_failing_listener_does_not_undo_a_change(rbc: RbcEmulator) -> None:
    def broken(_message: m.MovementAuthorityMessage) -> None:
        raise RuntimeError("listener bug")

    rbc.add_listener(broken)
    assert rbc.issue("URV1", _issue()).ma_id == 1
    assert rbc.current("URV1") is not None
    rbc.remove_listener(broken)
