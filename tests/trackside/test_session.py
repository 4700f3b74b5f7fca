"""The trackside side of the session: accept, reject with reasons, acknowledge, expire."""

from __future__ import annotations

from protocol import messages as m
from trackside.session import SessionManager


def request(vehicle: str = "URV1", versions: tuple[int, ...] = (1,)) -> m.SessionRequest:
    return m.SessionRequest(
        vehicle_id=vehicle, supported_versions=versions, etcs_id=1, train_length_m=6.0
    )


def report(seq: int, vehicle: str = "URV1") -> m.StatusReport:
    return m.StatusReport(
        vehicle_id=vehicle,
        seq=seq,
        sim_time_s=seq * 0.2,
        line_id="bologna-ring",
        position_m=0.0,
        speed_mps=0.0,
        acceleration_mps2=0.0,
        traction_force_n=0.0,
        ato_state=m.AtoState.NOT_AVAILABLE,
        etcs_mode=m.EtcsMode.SR,
        sc_state=m.ScState.OFF,
    )


def test_handshake_accepted_and_rejected_with_each_reason() -> None:
    manager = SessionManager("ts-1", response_timeout_s=2.0, in_charge_elsewhere={"URV9": "ts-2"})
    answer = manager.on_request(request(), 0.0)
    assert isinstance(answer, m.SessionAccept)
    assert (answer.version, answer.response_timeout_s) == (1, 2.0)
    versions = manager.on_request(request("URV2", versions=(2, 3)), 0.0)
    assert isinstance(versions, m.SessionReject)
    assert versions.reason is m.SessionRejectReason.INCOMPATIBLE_VERSIONS
    elsewhere = manager.on_request(request("URV9"), 0.0)
    assert isinstance(elsewhere, m.SessionReject)
    assert elsewhere.reason is m.SessionRejectReason.OTHER_TRACKSIDE_IN_CHARGE
    assert set(manager.sessions) == {"URV1"}
    assert manager.rejected == 2


def test_reports_are_acknowledged_once_and_stale_ones_counted() -> None:
    manager = SessionManager("ts-1")
    assert manager.on_status(report(0), 0.0) is None  # no session yet
    manager.on_request(request(), 0.0)
    ack = manager.on_status(report(5), 0.1)
    assert ack is not None
    assert ack.seq == 5
    assert manager.on_status(report(5), 0.2) is None
    assert manager.on_status(report(4), 0.3) is None
    assert manager.stale_reports == 2
    assert manager.reports_outside_session == 1


def test_a_silent_vehicle_loses_its_session_after_the_response_timeout() -> None:
    manager = SessionManager("ts-1", response_timeout_s=1.0)
    manager.on_request(request(), 0.0)
    manager.on_status(report(0), 0.5)
    assert manager.expire(1.5) == []
    assert manager.expire(1.6) == ["URV1"]
    assert manager.sessions == {}
    assert manager.lost == 1


def test_a_report_after_a_gap_longer_than_the_timeout_finds_the_session_lapsed() -> None:
    manager = SessionManager("ts-1", response_timeout_s=1.0)
    manager.on_request(request(), 0.0)
    assert manager.on_status(report(0), 0.5) is not None
    assert manager.on_status(report(1), 2.0) is None  # 1.5 s of silence, in the vehicle's time
    assert manager.sessions == {}
    assert manager.lost == 1
    manager.on_request(request(), 2.1)
    assert manager.close("URV1")
    assert not manager.close("URV1")
