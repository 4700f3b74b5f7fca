"""Hypothesis strategies for every wire message model."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from protocol import messages as m

vehicle_ids = st.from_regex(r"^[A-Za-z0-9_-]{1,32}$", fullmatch=True)
session_ids = st.from_regex(r"^[A-Za-z0-9_-]{8,64}$", fullmatch=True)
seals = st.none() | st.builds(m.Freshness, session_id=session_ids, number=st.integers(1, 2**53))
names = st.text(min_size=1, max_size=64)
finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
non_negative = st.floats(min_value=0.0, max_value=1e9, allow_nan=False)
counters = st.integers(min_value=0, max_value=2**53)


def _enum(enum: Any) -> st.SearchStrategy[Any]:
    return st.sampled_from(list(enum))


state_names = st.from_regex(r"^[a-z0-9_]{1,40}$", fullmatch=True)
operator_requests = st.builds(
    m.OperatorRequest,
    kind=_enum(m.OperatorRequestKind),
    number=st.integers(0, 255),
    raised_s=non_negative,
    deadline_s=st.none() | non_negative,
    confirmed=st.booleans(),
)
vital_control_statuses = st.builds(
    m.VitalControlStatus,
    eb_commanded=st.booleans(),
    system_decay=st.booleans(),
    decay_reasons=st.lists(state_names, max_size=3).map(tuple),
    eb_conditions=st.lists(st.integers(1, 6), max_size=6, unique=True).map(tuple),
    etcs_isolated=st.booleans(),
    supervision_state=state_names,
    brake_state=state_names,
    etcs_state=state_names,
    standstill=st.booleans(),
    odometry_efficient=st.booleans(),
    speed_mps=st.none() | non_negative,
    replicas=st.integers(1, 2),
    pair_tripped=st.booleans(),
    operator_requests=st.lists(operator_requests, max_size=4).map(tuple),
)

energy_statuses = st.builds(
    m.EnergyStatus,
    soc=st.none() | st.floats(0.0, 1.0),
    energy_to_go_j=st.none() | non_negative,
    energy_available_j=st.none() | non_negative,
    margin_j=st.none() | finite,
    range_extender_share=st.none() | st.floats(0.0, 1.0),
    short=st.booleans(),
    slowed=st.booleans(),
)

status_reports = st.builds(
    m.StatusReport,
    vehicle_id=vehicle_ids,
    seq=counters,
    sim_time_s=non_negative,
    line_id=names,
    position_m=finite,
    speed_mps=finite,
    acceleration_mps2=finite,
    traction_force_n=finite,
    ato_state=_enum(m.AtoState),
    etcs_mode=_enum(m.EtcsMode),
    sc_state=_enum(m.ScState),
    supervision_status=_enum(m.SupervisionStatus),
    target_speed_mps=st.none() | non_negative,
    journey_id=st.none() | names,
    position_confidence_m=st.none() | non_negative,
    next_timing_point_id=st.none() | names,
    arrivals=st.lists(
        st.builds(
            m.ArrivalEstimate,
            timing_point_id=names,
            scheduled_s=non_negative,
            estimated_s=non_negative,
        ),
        max_size=3,
    ).map(tuple),
    vital_control=st.none() | vital_control_statuses,
    track_data_version=st.none() | st.text(min_size=1, max_size=128),
    track_data_pending=st.none() | st.text(min_size=1, max_size=128),
    energy=st.none() | energy_statuses,
)

events = st.builds(
    m.Event,
    vehicle_id=vehicle_ids,
    seq=counters,
    sim_time_s=non_negative,
    severity=_enum(m.EventSeverity),
    code=st.from_regex(r"^[a-z0-9_.]{1,64}$", fullmatch=True),
    text=st.text(max_size=200),
)

command_bodies = st.one_of(
    st.just(m.PingCommand()),
    st.builds(
        m.RemoteDrivingTargetCommand,
        target_speed_mps=st.floats(min_value=0.0, max_value=100.0, allow_nan=False),
    ),
    st.just(m.EngageCommand()),
    st.just(m.DisengageCommand()),
    st.just(m.EmergencyBrakeCommand()),
    st.builds(
        m.OperatorConfirmCommand,
        request=_enum(m.OperatorRequestKind),
        number=st.integers(0, 255),
    ),
    st.builds(m.SkipStopCommand, timing_point_id=names),
    st.builds(m.TrainHoldCommand, hold=st.booleans()),
)

commands = st.builds(
    m.Command,
    vehicle_id=vehicle_ids,
    command_id=counters,
    issued_by=names,
    body=command_bodies,
    freshness=seals,
)

command_acks = st.builds(
    m.CommandAck,
    vehicle_id=vehicle_ids,
    command_id=counters,
    accepted=st.booleans(),
    reason=st.none() | st.text(max_size=256),
    sim_time_s=non_negative,
)

timing_points = st.builds(
    m.TimingPoint,
    id=names,
    position_m=non_negative,
    kind=_enum(m.TimingPointKind),
    arrival_time_s=non_negative,
    arrival_tolerance_s=non_negative,
    departure_time_s=st.none() | non_negative,
    minimum_dwell_s=non_negative,
    end_of_journey=st.just(False),
)


@st.composite
def journey_profiles(draw: st.DrawFn) -> m.JourneyProfile:
    points = draw(st.lists(timing_points, min_size=0, max_size=5))
    last = draw(timing_points).model_copy(update={"end_of_journey": True})
    return m.JourneyProfile(
        vehicle_id=draw(vehicle_ids),
        journey_id=draw(names),
        version=draw(counters),
        status=draw(_enum(m.JourneyProfileStatus)),
        line_id=draw(names),
        track_data_version=draw(st.text(min_size=1, max_size=128)),
        max_speed_mps=draw(st.none() | non_negative),
        timing_points=(*points, last),
    )


journey_profile_acks = st.builds(
    m.JourneyProfileAck,
    vehicle_id=vehicle_ids,
    journey_id=names,
    version=counters,
    accepted=st.booleans(),
    reason=st.none() | st.text(max_size=256),
)

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
    trackside_id=names,
    session_id=session_ids,
    version=st.integers(1, 1000),
    response_timeout_s=st.floats(min_value=0.001, max_value=600.0),
    status_interval_s=st.floats(min_value=0.001, max_value=60.0),
)

session_rejects = st.builds(
    m.SessionReject, trackside_id=names, reason=_enum(m.SessionRejectReason)
)

session_terminations = st.builds(
    m.SessionTermination,
    vehicle_id=vehicle_ids,
    by=st.sampled_from(["onboard", "trackside"]),
    reason=st.text(max_size=256),
)

line_version_requests = st.builds(m.LineVersionRequest, vehicle_id=vehicle_ids, line_id=names)
line_version_replies = st.builds(
    m.LineVersionReply, line_id=names, version=st.none() | st.text(min_size=1, max_size=128)
)
line_document_requests = st.builds(m.LineDocumentRequest, vehicle_id=vehicle_ids, line_id=names)
line_document_replies = st.builds(
    m.LineDocumentReply,
    line_id=names,
    version=st.none() | st.text(min_size=1, max_size=128),
    document=st.none() | st.text(max_size=2000),
)

chainages = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)
lengths = st.floats(min_value=1e-3, max_value=1e5, allow_nan=False)
ma_ids = st.integers(min_value=1, max_value=2**53)


@st.composite
def movement_authority_ends(draw: st.DrawFn) -> m.MovementAuthorityEnd:
    overlap = draw(st.booleans())
    danger_point_m = draw(st.just(0.0) | st.floats(min_value=0.0, max_value=1e3))
    overlap_m = danger_point_m + draw(lengths) if overlap else 0.0
    return m.MovementAuthorityEnd(
        end_of_authority_m=draw(chainages),
        danger_point_m=danger_point_m,
        overlap_m=overlap_m,
        overlap_timer_s=draw(st.none() | non_negative) if overlap else None,
        overlap_timer_start_m=draw(st.floats(min_value=0.0, max_value=1e3)) if overlap else 0.0,
        release_speed_mps=draw(st.none() | st.floats(min_value=0.0, max_value=100.0)),
    )


ma_sections = st.builds(
    m.MovementAuthoritySection,
    length_m=lengths,
    timer_s=st.none() | non_negative,
    timer_stop_m=st.floats(min_value=0.0, max_value=1e5),
)


@st.composite
def movement_authority_extents(draw: st.DrawFn) -> m.MovementAuthorityExtent:
    end = draw(movement_authority_ends())
    start_m = draw(chainages)
    sections = draw(st.lists(ma_sections, max_size=5))
    length_m = sum(section.length_m for section in sections) if sections else draw(lengths)
    return m.MovementAuthorityExtent(
        **end.model_dump(exclude={"end_of_authority_m"}),
        start_m=start_m,
        end_of_authority_m=start_m + length_m,
        sections=tuple(sections),
        track_description_m=draw(st.none() | lengths),
    )


@st.composite
def movement_authority_messages(draw: st.DrawFn) -> m.MovementAuthorityMessage:
    change = draw(_enum(m.MovementAuthorityChange))
    revoked = change is m.MovementAuthorityChange.REVOKED
    return m.MovementAuthorityMessage(
        vehicle_id=draw(vehicle_ids),
        ma_id=draw(ma_ids),
        change=change,
        issued_at_s=draw(non_negative),
        line_id=draw(names),
        line_version=draw(st.text(min_size=1, max_size=128)),
        authority=None if revoked else draw(movement_authority_extents()),
    )


movement_authority_requests = st.builds(m.MovementAuthorityRequest, vehicle_id=vehicle_ids)
movement_authority_replies = st.builds(
    m.MovementAuthorityReply,
    vehicle_id=vehicle_ids,
    movement_authority=st.none() | movement_authority_messages(),
)
movement_authority_acks = st.builds(
    m.MovementAuthorityAck,
    vehicle_id=vehicle_ids,
    ma_id=ma_ids,
    accepted=st.booleans(),
    reason=st.none() | st.text(max_size=256),
    sim_time_s=non_negative,
)


@st.composite
def speed_restriction_messages(draw: st.DrawFn) -> m.SpeedRestrictionMessage:
    start = draw(st.floats(0.0, 1e6, allow_nan=False))
    return m.SpeedRestrictionMessage(
        vehicle_id=draw(vehicle_ids),
        restriction_id=draw(st.from_regex(r"[a-z0-9_.:-]{1,64}", fullmatch=True)),
        line_id=draw(names),
        start_m=start,
        end_m=start + draw(st.floats(0.5, 1e5, allow_nan=False)),
        speed_mps=draw(st.none() | st.floats(0.1, 100.0, allow_nan=False)),
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
    m.LineDocumentRequest: line_document_requests,
    m.LineDocumentReply: line_document_replies,
    m.SessionRequest: session_requests,
    m.SessionAccept: session_accepts,
    m.SessionReject: session_rejects,
    m.SessionTermination: session_terminations,
    m.StatusAck: st.builds(m.StatusAck, vehicle_id=vehicle_ids, seq=st.integers(0, 2**31)),
    m.MovementAuthorityMessage: movement_authority_messages(),
    m.MovementAuthorityRequest: movement_authority_requests,
    m.MovementAuthorityReply: movement_authority_replies,
    m.MovementAuthorityAck: movement_authority_acks,
    m.SpeedRestrictionMessage: speed_restriction_messages(),
}
