"""The onboard side of the session: handshake, upkeep, loss, termination, stale packets."""

from __future__ import annotations

import pytest

from onboard.session import RETRY_S, ClientState, SessionClient
from protocol import messages as m
from trackside.session import SessionManager


def client() -> SessionClient:
    return SessionClient(vehicle_id="URV1", etcs_id=4711, train_length_m=6.0)


def accept(timeout_s: float = 3.0) -> m.SessionAccept:
    return m.SessionAccept(
        trackside_id="ts-1",
        session_id="session-1",
        version=1,
        response_timeout_s=timeout_s,
        status_interval_s=0.2,
    )


def test_an_accepted_handshake_establishes_the_session_with_the_tracksides_timing() -> None:
    c = client()
    request = c.request(0.0, track_data_version="abc")
    assert request is not None
    assert request.supported_versions == (1,)
    assert c.state is ClientState.CSR
    assert c.request(0.1, track_data_version="abc") is None  # one request at a time
    c.on_response(accept(timeout_s=2.5), 0.1)
    assert c.established
    assert c.trackside_id == "ts-1"
    assert c.response_timeout_s == 2.5
    assert c.status_interval_s == 0.2


def test_a_rejection_keeps_its_reason_and_the_retry_waits_thirty_seconds() -> None:
    c = client()
    c.request(0.0, track_data_version=None)
    c.on_response(
        m.SessionReject(trackside_id="ts-1", reason=m.SessionRejectReason.INCOMPATIBLE_VERSIONS),
        0.2,
    )
    assert c.state is ClientState.NCE
    assert c.reject_reason is m.SessionRejectReason.INCOMPATIBLE_VERSIONS
    assert c.request(0.2 + RETRY_S - 0.1, track_data_version=None) is None
    assert c.request(0.2 + RETRY_S, track_data_version=None) is not None


def test_one_status_report_outstanding_and_loss_without_acknowledgements() -> None:
    c = client()
    c.request(0.0, track_data_version=None)
    c.on_response(accept(timeout_s=1.0), 0.0)
    assert c.status_due(0.0, seq=0)
    assert not c.status_due(0.2, seq=1)  # seq 0 not acknowledged yet
    assert c.on_status_ack("URV1", 0, 0.25)
    assert c.status_due(0.25, seq=1)
    assert not c.on_status_ack("URV1", 0, 0.3)  # stale: already taken
    assert c.counters.stale == 1
    assert not c.step(1.2)  # heard at 0.25, timeout 1 s
    assert c.step(1.3)
    assert c.state is ClientState.NCE
    assert c.counters.lost == 1
    assert c.guard.session_id is None  # nothing of the lost session is taken any more
    # A lost session is asked for again at once (the trackside may have restarted); an
    # unanswered request waits for the retry.
    assert c.request(1.3, track_data_version=None) is not None
    c.on_response(None, 1.4)
    assert c.request(1.5, track_data_version=None) is None
    assert c.request(1.4 + c.retry_s, track_data_version=None) is not None


@pytest.mark.parametrize("fails", ["unanswered", "timed out"])
def test_a_trackside_back_while_a_request_is_out_is_asked_again_at_once(fails: str) -> None:
    """The session is lost while the link is down, and the request sent at once goes into the
    void; the trackside's token comes back before that request has failed. Its failure is then
    followed by a new request at once, not 30 s later (found by the two-router test, where the
    VC's vigilance went unanswered for want of a session while the link was long back)."""
    c = client()
    c.request(0.0, track_data_version=None)
    c.on_response(accept(timeout_s=3.0), 0.0)
    assert c.step(3.1)  # lost
    assert c.request(3.1, track_data_version=None) is not None
    c.trackside_appeared(4.0)  # while the request is out: nothing to do yet
    assert c.state is ClientState.CSR
    if fails == "unanswered":
        c.on_response(None, 4.5)
        failed_s = 4.5
    else:
        assert not c.step(3.1 + c.request_timeout_s + 0.1)
        failed_s = 3.1 + c.request_timeout_s + 0.1
    assert c.state is ClientState.NCE
    assert c.request(failed_s, track_data_version=None) is not None
    # That one failing too, the retry applies again.
    c.on_response(None, failed_s + 0.5)
    assert c.request(failed_s + 1.0, track_data_version=None) is None
    assert c.request(failed_s + 0.5 + c.retry_s, track_data_version=None) is not None


def test_stale_and_misaddressed_journey_profiles_are_rejected_and_counted() -> None:
    c = client()
    point = m.TimingPoint(
        id="tp",
        position_m=100.0,
        kind=m.TimingPointKind.STOPPING,
        arrival_time_s=60.0,
        end_of_journey=True,
    )

    def profile(version: int, vehicle: str = "URV1") -> m.JourneyProfile:
        return m.JourneyProfile(
            vehicle_id=vehicle,
            journey_id="j1",
            version=version,
            status=m.JourneyProfileStatus.VALID,
            line_id="bologna-ring",
            track_data_version="abc",
            timing_points=(point,),
        )

    assert c.on_journey_profile(profile(2), 0.0)
    assert not c.on_journey_profile(profile(2), 1.0)
    assert not c.on_journey_profile(profile(1), 1.0)
    assert c.on_journey_profile(profile(3), 2.0)
    assert not c.on_journey_profile(profile(4, vehicle="URV2"), 2.0)
    assert (c.counters.stale, c.counters.misaddressed) == (2, 1)


@pytest.mark.parametrize("by", ["onboard", "trackside"])
def test_termination_by_either_side(by: str) -> None:
    c = client()
    manager = SessionManager("ts-1")
    request = c.request(0.0, track_data_version=None)
    assert request is not None
    c.on_response(manager.on_request(request, 0.0), 0.0)
    assert c.established
    assert "URV1" in manager.sessions
    if by == "onboard":
        termination = c.terminate("end of mission", 5.0)
        assert termination is not None
        assert manager.on_termination(termination)
    else:
        termination = manager.terminate("URV1", "maintenance")
        assert termination is not None
        assert c.on_termination(termination, 5.0)
    assert c.state is ClientState.CST
    assert "URV1" not in manager.sessions
    assert c.request(5.0 + RETRY_S, track_data_version=None) is not None
