"""Hypothesis strategies for every wire message model."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from protocol import messages as m

vehicle_ids = st.from_regex(r"^[A-Za-z0-9_-]{1,32}$", fullmatch=True)
names = st.text(min_size=1, max_size=64)
finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
non_negative = st.floats(min_value=0.0, max_value=1e9, allow_nan=False)
counters = st.integers(min_value=0, max_value=2**53)


def _enum(enum: Any) -> st.SearchStrategy[Any]:
    return st.sampled_from(list(enum))


status_reports = st.builds(
    m.StatusReport,
    vehicle_id=vehicle_ids, seq=counters, sim_time_s=non_negative, line_id=names,
    position_m=finite, speed_mps=finite, acceleration_mps2=finite, traction_force_n=finite,
    ato_state=_enum(m.AtoState), etcs_mode=_enum(m.EtcsMode), sc_state=_enum(m.ScState),
    supervision_status=_enum(m.SupervisionStatus),
    target_speed_mps=st.none() | non_negative,
    journey_id=st.none() | names,
)  # fmt: skip

events = st.builds(
    m.Event,
    vehicle_id=vehicle_ids, seq=counters, sim_time_s=non_negative,
    severity=_enum(m.EventSeverity), code=st.from_regex(r"^[a-z0-9_.]{1,64}$", fullmatch=True),
    text=st.text(max_size=200),
)  # fmt: skip

command_bodies = st.one_of(
    st.just(m.PingCommand()),
    st.builds(
        m.RemoteDrivingTargetCommand,
        target_speed_mps=st.floats(min_value=0.0, max_value=100.0, allow_nan=False),
    ),
    st.just(m.EngageCommand()),
    st.just(m.DisengageCommand()),
)

commands = st.builds(
    m.Command, vehicle_id=vehicle_ids, command_id=counters, issued_by=names, body=command_bodies
)

command_acks = st.builds(
    m.CommandAck,
    vehicle_id=vehicle_ids, command_id=counters, accepted=st.booleans(),
    reason=st.none() | st.text(max_size=256), sim_time_s=non_negative,
)  # fmt: skip

timing_points = st.builds(
    m.TimingPoint,
    id=names, position_m=non_negative, kind=_enum(m.TimingPointKind),
    arrival_time_s=non_negative, arrival_tolerance_s=non_negative,
    departure_time_s=st.none() | non_negative, minimum_dwell_s=non_negative,
    end_of_journey=st.just(False),
)  # fmt: skip


@st.composite
def journey_profiles(draw: st.DrawFn) -> m.JourneyProfile:
    points = draw(st.lists(timing_points, min_size=0, max_size=5))
    last = draw(timing_points).model_copy(update={"end_of_journey": True})
    return m.JourneyProfile(
        vehicle_id=draw(vehicle_ids), journey_id=draw(names), version=draw(counters),
        status=draw(_enum(m.JourneyProfileStatus)), line_id=draw(names),
        track_data_version=draw(st.text(min_size=1, max_size=128)),
        max_speed_mps=draw(st.none() | non_negative), timing_points=(*points, last),
    )  # fmt: skip


journey_profile_acks = st.builds(
    m.JourneyProfileAck,
    vehicle_id=vehicle_ids, journey_id=names, version=counters, accepted=st.booleans(),
    reason=st.none() | st.text(max_size=256),
)  # fmt: skip

session_requests = st.builds(
    m.SessionRequest,
    vehicle_id=vehicle_ids,
    supported_versions=st.lists(st.integers(0, 1000), min_size=1, max_size=16).map(tuple),
    etcs_id=st.integers(0, 2**24 - 1),
    train_length_m=st.floats(min_value=0.1, max_value=1500.0),
    track_data_version=st.none() | st.text(max_size=128),
)

session_accepts = st.builds(
    m.SessionAccept,
    trackside_id=names, version=st.integers(1, 1000),
    response_timeout_s=st.floats(min_value=0.001, max_value=600.0),
    status_interval_s=st.floats(min_value=0.001, max_value=60.0),
)  # fmt: skip

session_rejects = st.builds(
    m.SessionReject, trackside_id=names, reason=_enum(m.SessionRejectReason)
)

session_terminations = st.builds(
    m.SessionTermination,
    vehicle_id=vehicle_ids, by=st.sampled_from(["onboard", "trackside"]),
    reason=st.text(max_size=256),
)  # fmt: skip

line_version_requests = st.builds(m.LineVersionRequest, vehicle_id=vehicle_ids, line_id=names)
line_version_replies = st.builds(
    m.LineVersionReply, line_id=names, version=st.none() | st.text(min_size=1, max_size=128)
)

STRATEGIES: dict[type[m.Message], st.SearchStrategy[Any]] = {
    m.StatusReport: status_reports,
    m.Event: events,
    m.Command: commands,
    m.CommandAck: command_acks,
    m.JourneyProfile: journey_profiles(),
    m.JourneyProfileAck: journey_profile_acks,
    m.LineVersionRequest: line_version_requests,
    m.LineVersionReply: line_version_replies,
    m.SessionRequest: session_requests,
    m.SessionAccept: session_accepts,
    m.SessionReject: session_rejects,
    m.SessionTermination: session_terminations,
}
