"""Trackside ↔ onboard messages: pydantic v2 models carried as JSON over Zenoh.

Every message forbids unknown fields, carries ``schema_version`` and uses SI units (m, s, m/s,
m/s², N). The session messages follow SUBSET-126 in spirit (DOMAIN.md §2.3): a handshake request
(HSReq), its acceptance (HSAck) or rejection (HSRej), a termination; journey profiles (JP) are
delivered and acknowledged (JPAck); status reports (STR) flow periodically. The RBC emulator of
the trackside sends movement authorities (MA, after SUBSET-026 packet 15, DOMAIN.md §1.7) and the
onboard acknowledges them.

Abbreviations: ATO (automatic train operation), ATO-OB / ATO-TS (onboard / trackside), ETCS
(European Train Control System), SC (supervisory controller of the ADF), ADF (autonomous driving
function), RD / AD (remote / autonomous driving), JP (journey profile), TP (timing point),
EB (emergency brake), STR (status report), RBC (radio block centre), MA (movement authority),
EoA (end of authority), SvL (supervised location).
"""

from __future__ import annotations

import math
from enum import StrEnum
from typing import Annotated, Literal, Self

from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "SCHEMA_VERSION",
    "ArrivalEstimate",
    "AtoState",
    "Command",
    "CommandAck",
    "CommandBody",
    "EngageCommand",
    "DisengageCommand",
    "EmergencyBrakeCommand",
    "EtcsMode",
    "EnergyStatus",
    "Event",
    "EventSeverity",
    "Freshness",
    "JourneyProfile",
    "JourneyProfileAck",
    "JourneyProfileStatus",
    "LineDocumentReply",
    "LineDocumentRequest",
    "LineVersionReply",
    "LineVersionRequest",
    "Message",
    "MovementAuthorityAck",
    "MovementAuthorityChange",
    "MovementAuthorityEnd",
    "MovementAuthorityExtent",
    "MovementAuthorityMessage",
    "MovementAuthorityReply",
    "MovementAuthorityRequest",
    "MovementAuthoritySection",
    "OperatorConfirmCommand",
    "OperatorRequest",
    "OperatorRequestKind",
    "PingCommand",
    "RemoteDrivingTargetCommand",
    "ScState",
    "SessionAccept",
    "SessionReject",
    "SessionRejectReason",
    "SessionRequest",
    "SpeedRestrictionMessage",
    "SessionResponse",
    "SessionTermination",
    "SkipStopCommand",
    "StatusAck",
    "StatusReport",
    "SupervisionStatus",
    "TimingPoint",
    "TimingPointKind",
    "TrainHoldCommand",
    "VitalControlStatus",
]

SCHEMA_VERSION = 1
"""Version of the message schemas in this module; bumped on any incompatible change."""

VehicleId = Annotated[
    str,
    Field(min_length=1, max_length=32, pattern=r"^[A-Za-z0-9_-]+$", description="Vehicle id"),
]
NonNegativeFloat = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
LineId = Annotated[str, Field(min_length=1, max_length=64, description="Line id")]


class AtoState(StrEnum):
    """ATO-OB states of SUBSET-125 §9 (DOMAIN.md §2.1)."""

    NP = "NP"
    CONFIGURATION = "CO"
    NOT_AVAILABLE = "NA"
    AVAILABLE = "AV"
    READY = "RE"
    ENGAGED = "EG"
    DISENGAGING = "DE"
    FAILURE = "FA"


class EtcsMode(StrEnum):
    """ETCS onboard modes of SUBSET-026 §4 (Baseline 4 list, DOMAIN.md §1.6)."""

    NP = "NP"
    SB = "SB"
    PS = "PS"
    SH = "SH"
    SM = "SM"
    FS = "FS"
    AD = "AD"
    LS = "LS"
    SR = "SR"
    OS = "OS"
    SL = "SL"
    NL = "NL"
    UN = "UN"
    TR = "TR"
    PT = "PT"
    SF = "SF"
    IS = "IS"
    SN = "SN"
    RV = "RV"


class ScState(StrEnum):
    """States of the ADF supervisory controller (seed 000 §5)."""

    OFF = "OFF"
    AD = "AD"
    RD = "RD"
    HRD2AD = "HRD2AD"
    HAD2RD = "HAD2RD"


class SupervisionStatus(StrEnum):
    """ETCS supervision statuses (SUBSET-026 §3.13.10)."""

    NORMAL = "normal"
    INDICATION = "indication"
    OVERSPEED = "overspeed"
    WARNING = "warning"
    INTERVENTION = "intervention"


class Message(BaseModel):
    """Base of every wire message: frozen, no unknown fields, versioned."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    schema_version: Literal[1] = Field(default=1, description="Message schema, SCHEMA_VERSION")


class Freshness(BaseModel):
    """Which session a trackside message belongs to, and its number in it (EN 50159's
    identifier and sequence number): the onboard takes a command, a journey profile, an MA or a
    TSR only from the session it holds, and each number once (``onboard.freshness``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    session_id: str = Field(
        min_length=8,
        max_length=64,
        pattern=r"^[A-Za-z0-9_-]+$",
        description="The session's id, given by the trackside in its HSAck",
    )
    number: int = Field(
        ge=1, le=2**53, description="The trackside's counter in the session, +1 per message"
    )


_FRESHNESS = "The session and number it was sent in (none: refused on board)"


class ArrivalEstimate(BaseModel):
    """When the vehicle expects to reach a timing point of its journey."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    timing_point_id: str = Field(min_length=1, max_length=64)
    scheduled_s: NonNegativeFloat = Field(description="Planned arrival, from journey start [s]")
    estimated_s: NonNegativeFloat = Field(description="Estimated arrival, from journey start [s]")


class OperatorRequestKind(StrEnum):
    """What the Vital Control asks of the remote operator through the ATO-OB (seeds 001, 004)."""

    VIGILANCE = "vigilance"
    """Operator Vigilance: the operator confirms he is watching, before its time limit."""
    EB_REARM = "eb_rearm"
    """EB Rearm Confirmation: the EB may be released (standstill, no hazard)."""
    ETCS_ISOLATION = "etcs_isolation"
    """ETCS Isolation Confirmation: offered at standstill with ETCS inserted."""
    ETCS_INSERTION = "etcs_insertion"
    """ETCS Insertion Confirmation: offered at standstill with ETCS isolated."""


class OperatorRequest(BaseModel):
    """One request of the Vital Control waiting for the operator; ``number`` binds the answer."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    kind: OperatorRequestKind
    number: int = Field(ge=0, le=255, description="The request's sequence number (one byte)")
    raised_s: NonNegativeFloat = Field(description="When the ATO-OB first saw it [s]")
    deadline_s: NonNegativeFloat | None = Field(
        default=None, description="When an unanswered request brakes the train [s], if ever"
    )
    confirmed: bool = Field(default=False, description="The operator's answer is on board")


StateName = Annotated[str, Field(min_length=1, max_length=40, pattern=r"^[a-z0-9_]+$")]


class VitalControlStatus(BaseModel):
    """The Vital Control module's state, as the ATO-OB reports it (seeds 001, 004)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    eb_commanded: bool = Field(description="The EB valves are de-energised")
    system_decay: bool = Field(description="Stopped until the onboard systems are restarted")
    decay_reasons: tuple[StateName, ...] = Field(default=(), max_length=16)
    eb_conditions: tuple[int, ...] = Field(
        default=(), max_length=6, description="EB conditions 1–6 that hold now"
    )
    etcs_isolated: bool
    supervision_state: StateName = Field(description="Task B: monitoring, eb_demanded, decayed")
    brake_state: StateName = Field(description="Task C's EB: released, braking, standstill, …")
    etcs_state: StateName = Field(description="Task C's relay: inserted, isolating, isolated, …")
    standstill: bool
    odometry_efficient: bool
    speed_mps: NonNegativeFloat | None = Field(
        default=None, description="The VC's own speed, from its tachometer board [m/s]"
    )
    replicas: int = Field(default=1, ge=1, le=2, description="1, or 2 in 2-out-of-2")
    pair_tripped: bool = Field(
        default=False, description="2oo2: a disagreement or a watchdog expiry braked the train"
    )
    operator_requests: tuple[OperatorRequest, ...] = Field(default=(), max_length=8)


class EnergyStatus(BaseModel):
    """The Energy Manager's reckoning (seed 000): the energy to finish the journey against what
    the batteries and the range extender hold, at the DC bus [J]."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    soc: float | None = Field(
        default=None,
        ge=0.0,
        le=1.0,
        description="The batteries' state of charge, as the BMS reports it [1]",
    )
    energy_to_go_j: NonNegativeFloat | None = Field(
        default=None, description="Energy to finish the journey: traction and auxiliaries [J]"
    )
    energy_available_j: NonNegativeFloat | None = Field(
        default=None, description="What the batteries (above their floor) and the RE can give [J]"
    )
    margin_j: FiniteFloat | None = Field(
        default=None, description="Available − to go [J]; None without a journey or a SOC"
    )
    range_extender_share: float | None = Field(
        default=None, ge=0.0, le=1.0, description="Share of the energy to go the RE gives at most"
    )
    short: bool = Field(default=False, description="The margin is under the reserve")
    slowed: bool = Field(
        default=False, description="The plan uses the arrival windows to save energy"
    )


class StatusReport(Message):
    """Periodic status of one vehicle (the STR), published at the report interval."""

    vehicle_id: VehicleId
    seq: int = Field(ge=0, description="Report counter, +1 per report")
    sim_time_s: NonNegativeFloat = Field(description="Onboard simulated time [s]")
    line_id: str = Field(min_length=1, max_length=64, description="Line the vehicle runs on")
    position_m: FiniteFloat = Field(description="Estimated front-end chainage [m]")
    speed_mps: FiniteFloat = Field(description="Estimated speed [m/s]")
    acceleration_mps2: FiniteFloat = Field(description="Estimated acceleration [m/s²]")
    traction_force_n: FiniteFloat = Field(description="Applied longitudinal force u [N]")
    ato_state: AtoState
    etcs_mode: EtcsMode
    sc_state: ScState
    supervision_status: SupervisionStatus = SupervisionStatus.NORMAL
    target_speed_mps: NonNegativeFloat | None = Field(
        default=None, description="Remote-driving target speed [m/s], when one is set"
    )
    journey_id: str | None = Field(default=None, max_length=64, description="Accepted journey")
    position_confidence_m: NonNegativeFloat | None = Field(
        default=None, description="Half-width of the odometry confidence interval [m]"
    )
    next_timing_point_id: str | None = Field(
        default=None, max_length=64, description="The next timing point of the journey"
    )
    arrivals: tuple[ArrivalEstimate, ...] = Field(
        default=(), max_length=500, description="Estimated arrivals at the timing points ahead"
    )
    vital_control: VitalControlStatus | None = Field(
        default=None, description="The Vital Control module, on vehicles fitted with one"
    )
    permitted_speed_mps: NonNegativeFloat | None = Field(
        default=None, description="ETCS permitted speed at the front end [m/s]"
    )
    intervention_speed_mps: NonNegativeFloat | None = Field(
        default=None, description="ETCS intervention speed now [m/s]; None when unsupervised"
    )
    reference_speed_mps: NonNegativeFloat | None = Field(
        default=None, description="The ADF's reference speed now (ODP in AD, target in RD) [m/s]"
    )
    train_hold: bool = Field(default=False, description="Held at the next stopping point")
    track_data_version: str | None = Field(
        default=None,
        max_length=128,
        description="The version (SHA-256) of the track data the onboard drives on",
    )
    track_data_pending: str | None = Field(
        default=None,
        max_length=128,
        description="A newer version received and verified, waiting for standstill to switch",
    )
    energy: EnergyStatus | None = Field(
        default=None, description="The Energy Manager's reckoning (absent from older onboards)"
    )


class EventSeverity(StrEnum):
    INFO = "info"
    WARNING = "warning"
    ERROR = "error"


class Event(Message):
    """A notable onboard occurrence, delivered reliably in order."""

    vehicle_id: VehicleId
    seq: int = Field(ge=0, description="Event counter, +1 per event")
    sim_time_s: NonNegativeFloat = Field(description="Onboard simulated time [s]")
    severity: EventSeverity
    code: str = Field(min_length=1, max_length=64, pattern=r"^[a-z0-9_.]+$")
    text: str = Field(max_length=1024)


class PingCommand(BaseModel):
    """Asks the vehicle to acknowledge; used for link checks and latency measurement."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    type: Literal["ping"] = "ping"


class RemoteDrivingTargetCommand(BaseModel):
    """The remote driver's target speed for remote driving (RD)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    type: Literal["rd_target_speed"] = "rd_target_speed"
    target_speed_mps: float = Field(ge=0.0, le=100.0, allow_inf_nan=False)


class EngageCommand(BaseModel):
    """The driver's "ATO Engage"."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    type: Literal["engage"] = "engage"


class DisengageCommand(BaseModel):
    """The driver's "ATO Disengage"."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    type: Literal["disengage"] = "disengage"


class EmergencyBrakeCommand(BaseModel):
    """The remote operator's emergency brake: relayed to the Vital Control, which applies it."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    type: Literal["emergency_brake"] = "emergency_brake"


class OperatorConfirmCommand(BaseModel):
    """The operator's answer to one Vital Control request (vigilance, EB rearm, ETCS isolation
    or insertion), bound to the request's number so that it answers nothing newer."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    type: Literal["operator_confirm"] = "operator_confirm"
    request: OperatorRequestKind
    number: int = Field(ge=0, le=255, description="The number of the request answered")


class SkipStopCommand(BaseModel):
    """The driver's "Skip Stopping Point": run through a stopping point of the journey."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    type: Literal["skip_stop"] = "skip_stop"
    timing_point_id: str = Field(min_length=1, max_length=64)


class TrainHoldCommand(BaseModel):
    """The ATO-TS's train hold: stay at the stopping point reached next until released."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    type: Literal["train_hold"] = "train_hold"
    hold: bool


CommandBody = Annotated[
    PingCommand
    | RemoteDrivingTargetCommand
    | EngageCommand
    | DisengageCommand
    | EmergencyBrakeCommand
    | OperatorConfirmCommand
    | SkipStopCommand
    | TrainHoldCommand,
    Field(discriminator="type"),
]


class Command(Message):
    """A trackside command to one vehicle, answered by a :class:`CommandAck`."""

    vehicle_id: VehicleId
    command_id: int = Field(ge=0, description="Issuer's counter, echoed in the ack")
    issued_by: str = Field(min_length=1, max_length=64, description="User or service")
    body: CommandBody
    freshness: Freshness | None = Field(default=None, description=_FRESHNESS)


class CommandAck(Message):
    """The vehicle's answer to a command: accepted for execution, or rejected with a reason."""

    vehicle_id: VehicleId
    command_id: int = Field(ge=0)
    accepted: bool
    reason: str | None = Field(default=None, max_length=256)
    sim_time_s: NonNegativeFloat


class TimingPointKind(StrEnum):
    STOPPING = "stopping"
    PASSING = "passing"
    SKIP = "skip"


class TimingPoint(BaseModel):
    """A timing point (TP) of a journey profile, located on the line."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: str = Field(min_length=1, max_length=64)
    position_m: FiniteFloat = Field(ge=0.0, description="Stopping or passing chainage [m]")
    kind: TimingPointKind
    arrival_time_s: NonNegativeFloat = Field(description="Planned arrival, from journey start [s]")
    arrival_tolerance_s: NonNegativeFloat = Field(default=0.0, description="T_ARRIVAL_WINDOW [s]")
    departure_time_s: NonNegativeFloat | None = Field(default=None, description="Departure [s]")
    minimum_dwell_s: NonNegativeFloat = Field(default=0.0, description="Minimum dwell [s]")
    end_of_journey: bool = False


class JourneyProfileStatus(StrEnum):
    INVALID = "invalid"
    VALID = "valid"
    UNAVAILABLE = "unavailable"
    UPDATE = "update"
    OVERWRITE = "overwrite"


class JourneyProfile(Message):
    """A journey profile delivered to a vehicle (SUBSET-125 §6.4, reduced)."""

    vehicle_id: VehicleId
    journey_id: str = Field(min_length=1, max_length=64)
    version: int = Field(ge=0)
    status: JourneyProfileStatus
    line_id: str = Field(min_length=1, max_length=64)
    track_data_version: str = Field(min_length=1, max_length=128, description="Line hash")
    max_speed_mps: NonNegativeFloat | None = Field(default=None, description="Journey cap [m/s]")
    timing_points: tuple[TimingPoint, ...] = Field(min_length=1)
    freshness: Freshness | None = Field(default=None, description=_FRESHNESS)

    @model_validator(mode="after")
    def _one_end_of_journey_last(self) -> Self:
        ends = [index for index, tp in enumerate(self.timing_points) if tp.end_of_journey]
        if ends != [len(self.timing_points) - 1]:
            raise ValueError("exactly one timing point must be the end of journey, and the last")
        return self


class JourneyProfileAck(Message):
    """The vehicle's acceptance or rejection of a journey profile (JPAck)."""

    vehicle_id: VehicleId
    journey_id: str = Field(min_length=1, max_length=64)
    version: int = Field(ge=0)
    accepted: bool
    reason: str | None = Field(default=None, max_length=256)


class LineVersionRequest(Message):
    """An onboard asks which version of a line the trackside holds."""

    vehicle_id: VehicleId
    line_id: str = Field(min_length=1, max_length=64)


class LineVersionReply(Message):
    """The trackside's current version of a line, or ``None`` if it does not know the line."""

    line_id: str = Field(min_length=1, max_length=64)
    version: str | None = Field(default=None, max_length=128)


MAX_LINE_DOCUMENT_CHARS = 64_000_000
"""The largest line document carried over Zenoh [characters of canonical JSON]: a line of
several hundred kilometres with its geodetic polyline stays far below it."""


class LineDocumentRequest(Message):
    """An onboard asks the trackside for a line's document (its track data), to load it."""

    vehicle_id: VehicleId
    line_id: str = Field(min_length=1, max_length=64)


class LineDocumentReply(Message):
    """The trackside's current version of a line and its document (the canonical JSON whose
    SHA-256 is the version); both ``None`` if it does not hold the line. The onboard checks
    the SHA-256 before it stores or uses the document."""

    line_id: str = Field(min_length=1, max_length=64)
    version: str | None = Field(default=None, max_length=128)
    document: str | None = Field(default=None, max_length=MAX_LINE_DOCUMENT_CHARS)


class SessionRequest(Message):
    """Handshake request from an onboard (HSReq)."""

    vehicle_id: VehicleId
    supported_versions: tuple[int, ...] = Field(min_length=1, max_length=16)
    etcs_id: int = Field(ge=0, lt=2**24, description="NID_ENGINE")
    train_length_m: float = Field(gt=0.0, le=1500.0, allow_inf_nan=False)
    track_data_version: str | None = Field(default=None, max_length=128)


class SessionAccept(Message):
    """Handshake acceptance (HSAck)."""

    type: Literal["accept"] = "accept"
    trackside_id: str = Field(min_length=1, max_length=64)
    session_id: str = Field(
        min_length=8,
        max_length=64,
        pattern=r"^[A-Za-z0-9_-]+$",
        description="The session's id, carried by every message the trackside sends in it",
    )
    version: int = Field(ge=1)
    response_timeout_s: float = Field(gt=0.0, le=600.0, allow_inf_nan=False)
    status_interval_s: float = Field(gt=0.0, le=60.0, allow_inf_nan=False)


class SessionRejectReason(StrEnum):
    INCOMPATIBLE_VERSIONS = "incompatible_versions"
    OTHER_TRACKSIDE_IN_CHARGE = "other_trackside_in_charge"
    TRACKSIDE_IN_CHARGE_UNKNOWN = "trackside_in_charge_unknown"


class SessionReject(Message):
    """Handshake rejection (HSRej) with its reason."""

    type: Literal["reject"] = "reject"
    trackside_id: str = Field(min_length=1, max_length=64)
    reason: SessionRejectReason


SessionResponse = Annotated[SessionAccept | SessionReject, Field(discriminator="type")]


class StatusAck(Message):
    """The trackside's acknowledgement of a status report (STRAck): one report may be
    outstanding at a time, and a session with no acknowledgement within the response timeout
    is lost."""

    vehicle_id: VehicleId
    seq: int = Field(ge=0, description="The acknowledged report's counter")


class SessionTermination(Message):
    """Either side ends the session (SESSTerm / SESSTermReq)."""

    vehicle_id: VehicleId
    by: Literal["onboard", "trackside"]
    reason: str = Field(max_length=256)


class MovementAuthoritySection(BaseModel):
    """A section of an MA (L_SECTION) with its optional timer (Q_SECTIONTIMER)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    length_m: PositiveFloat = Field(description="L_SECTION: length of the section [m]")
    timer_s: NonNegativeFloat | None = Field(
        default=None, description="T_SECTIONTIMER, counted from the MA's reception [s]"
    )
    timer_stop_m: NonNegativeFloat = Field(
        default=0.0,
        description="D_SECTIONTIMERSTOPLOC: from the section's start to where the timer stops [m]",
    )


_MA_LENGTH_TOLERANCE_REL = 1e-9
_MA_LENGTH_TOLERANCE_M = 1e-6
"""How closely the sections must add up to the MA's length: the onboard's own tolerance."""


class MovementAuthorityEnd(BaseModel):
    """The end of an MA: the EoA's chainage and what lies beyond it (packet 15's end fields).

    The danger point, the overlap, their timers and the release speed belong to the location of
    the EoA, so an extension or a shortening gives them afresh with the new EoA.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    end_of_authority_m: FiniteFloat = Field(description="Chainage of the end of authority [m]")
    danger_point_m: NonNegativeFloat = Field(
        default=0.0, description="D_DP: from the EoA to the danger point [m]; 0 for none"
    )
    overlap_m: NonNegativeFloat = Field(
        default=0.0, description="D_OL: from the EoA to the end of the overlap [m]; 0 for none"
    )
    overlap_timer_s: NonNegativeFloat | None = Field(
        default=None, description="T_OL: overlap timer [s]; none for no timer"
    )
    overlap_timer_start_m: NonNegativeFloat = Field(
        default=0.0, description="D_STARTOL: the overlap timer starts this far before the EoA [m]"
    )
    release_speed_mps: NonNegativeFloat | None = Field(
        default=None, description="Release speed [m/s]; none: calculated on board"
    )

    @model_validator(mode="after")
    def _overlap_consistent(self) -> Self:
        if self.overlap_m and self.overlap_m < self.danger_point_m:
            raise ValueError(
                f"the overlap ({self.overlap_m} m) must end beyond the danger point "
                f"({self.danger_point_m} m)"
            )
        if not self.overlap_m and (self.overlap_timer_s is not None or self.overlap_timer_start_m):
            raise ValueError("an overlap timer needs an overlap (overlap_m > 0)")
        return self

    @property
    def supervised_location_m(self) -> float:
        """Chainage of the SvL [m]: end of overlap, else danger point, else EoA."""
        return self.end_of_authority_m + (self.overlap_m or self.danger_point_m)


class MovementAuthorityExtent(MovementAuthorityEnd):
    """Where an MA reaches: from ``start_m`` (the reference location) to its end.

    Chainages are the line's. On a ring the EoA is unwrapped from the start: it may exceed the
    line's length, and ``end_of_authority_m - start_m`` is always the MA's length. The onboard
    takes ``start_m`` as the MA's reference and the other fields as distances from it or from
    the EoA, as in packet 15.
    """

    start_m: FiniteFloat = Field(description="Chainage of the MA's start, its reference [m]")
    sections: tuple[MovementAuthoritySection, ...] = Field(
        default=(), max_length=32, description="Sections from the start; they add up to the EoA"
    )
    track_description_m: PositiveFloat | None = Field(
        default=None,
        description="From the start, how far the SSP and gradient sent with the MA reach [m]; "
        "none: up to the SvL",
    )

    @model_validator(mode="after")
    def _end_beyond_start(self) -> Self:
        length_m = self.length_m
        if not length_m > 0.0:
            raise ValueError(
                f"the EoA ({self.end_of_authority_m} m) must lie beyond the start "
                f"({self.start_m} m)"
            )
        if self.sections:
            total_m = sum(section.length_m for section in self.sections)
            if not math.isclose(
                total_m, length_m, rel_tol=_MA_LENGTH_TOLERANCE_REL, abs_tol=_MA_LENGTH_TOLERANCE_M
            ):
                raise ValueError(
                    f"the sections add up to {total_m} m, not the MA's length {length_m} m"
                )
        return self

    @property
    def length_m(self) -> float:
        """From the start to the EoA [m]."""
        return self.end_of_authority_m - self.start_m


class MovementAuthorityChange(StrEnum):
    """What an RBC message did to the vehicle's MA."""

    ISSUED = "issued"
    EXTENDED = "extended"
    SHORTENED = "shortened"
    REVOKED = "revoked"
    """Withdrawn: the onboard applies it as an unconditional emergency stop."""


class MovementAuthorityMessage(Message):
    """An MA from the RBC to one vehicle: granted (issued, extended, shortened) or revoked.

    ``ma_id`` grows by one with every change for the vehicle, so the onboard can drop a stale
    or repeated one; ``authority`` is ``None`` exactly when the MA is revoked.
    """

    vehicle_id: VehicleId
    ma_id: int = Field(ge=1, description="The RBC's counter for the vehicle, +1 per change")
    change: MovementAuthorityChange
    issued_at_s: NonNegativeFloat = Field(description="Issue time on the RBC's clock [s]")
    line_id: LineId
    line_version: str = Field(min_length=1, max_length=128, description="Track-data version")
    authority: MovementAuthorityExtent | None = Field(
        description="The MA granted; none when revoked"
    )
    freshness: Freshness | None = Field(default=None, description=_FRESHNESS)

    @model_validator(mode="after")
    def _authority_unless_revoked(self) -> Self:
        revoked = self.change is MovementAuthorityChange.REVOKED
        if revoked != (self.authority is None):
            raise ValueError("a revoked MA carries no authority, and every other MA carries one")
        return self


class MovementAuthorityRequest(Message):
    """An onboard asks for its current MA (at start-up, or after it lost the stream)."""

    vehicle_id: VehicleId


class MovementAuthorityAck(Message):
    """The onboard's acknowledgement of an MA: applied, or refused with a reason."""

    vehicle_id: VehicleId
    ma_id: int = Field(ge=1)
    accepted: bool
    reason: str | None = Field(default=None, max_length=256)
    sim_time_s: NonNegativeFloat = Field(description="Onboard simulated time [s]")


class SpeedRestrictionMessage(Message):
    """A temporary speed restriction from the RBC to one vehicle (ETCS packets 65 and 66): put
    in force over ``[start_m, end_m)`` of the line, or revoked when ``speed_mps`` is ``None``."""

    vehicle_id: VehicleId
    restriction_id: str = Field(
        min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.:-]+$", description="The TSR's id"
    )
    line_id: LineId
    start_m: NonNegativeFloat = Field(description="Start, chainage [m]")
    end_m: float = Field(gt=0.0, allow_inf_nan=False, description="End, chainage [m]")
    speed_mps: float | None = Field(
        gt=0.0, le=100.0, allow_inf_nan=False, description="Speed limit [m/s]; null: revoked"
    )
    freshness: Freshness | None = Field(default=None, description=_FRESHNESS)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.end_m <= self.start_m:
            raise ValueError("end_m must lie after start_m")
        return self


class MovementAuthorityReply(Message):
    """The RBC's current MA for the vehicle (``None`` when it holds none) and the TSRs in
    force for it: what an onboard asks for at start-up and after a new session."""

    vehicle_id: VehicleId
    movement_authority: MovementAuthorityMessage | None = None
    speed_restrictions: tuple[SpeedRestrictionMessage, ...] = Field(default=(), max_length=256)
