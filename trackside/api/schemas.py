"""Request and response bodies of the REST API, every resource's in one place.

Names follow what a body is for: ``XCreate`` for a body that makes a resource, ``XPublic`` for
what is returned, ``XRequest`` for the body of a command to a vehicle. SI units in every field,
km/h only where a person types a speed (``target_speed_kmh``, ``speed_kmh``).
"""

from __future__ import annotations

import json
from datetime import datetime
from enum import StrEnum
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from protocol import messages as m
from trackdb.journey import Journey, JourneyCheck
from trackdb.storage import LineSummary
from trackside.bridge import VehicleSnapshot
from trackside.models import AuditEntry, Role, TelemetrySample, User, VehicleEvent
from trackside.services.audit import AuditResult
from trackside.services.commands import JourneySent
from trackside.services.journeys import StoredJourney
from trackside.services.lines import LineProfile

__all__ = [
    "AuditPublic",
    "CommandAckPublic",
    "ConfirmRequest",
    "ConfirmationKind",
    "EmptyRequest",
    "EventPublic",
    "HoldPublic",
    "JourneyCheckPublic",
    "JourneyProfileAckPublic",
    "JourneyProfileRequest",
    "JourneyPublic",
    "LegPublic",
    "LinePublic",
    "LineProfilePublic",
    "LineRejectedPublic",
    "LineVersionPublic",
    "LineVersionRef",
    "MovementAuthorityPublic",
    "PasswordReset",
    "ProblemsPublic",
    "RefusedPublic",
    "SkipStopRequest",
    "SpeedRestrictionCreate",
    "TargetSpeedRequest",
    "TelemetryPublic",
    "TokenPublic",
    "TrainHoldRequest",
    "UserCreate",
    "UserPublic",
    "VehiclePublic",
    "VehicleStatusPublic",
]


# -- auth and users ----------------------------------------------------------------------------


class TokenPublic(BaseModel):
    access_token: str
    token_type: str = "bearer"


class UserCreate(BaseModel):
    username: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")
    password: str = Field(min_length=8, max_length=256)
    role: Role


class PasswordReset(BaseModel):
    """A user's new password, set by an admin (the user's tokens are revoked)."""

    password: str = Field(min_length=8, max_length=256)


class UserPublic(BaseModel):
    username: str
    role: Role
    disabled: bool = False

    @classmethod
    def from_user(cls, user: User) -> UserPublic:
        return cls(username=user.username, role=Role(user.role), disabled=bool(user.disabled))


# -- vehicles ----------------------------------------------------------------------------------


REPORT_ONLY_FIELDS: set[str] = {"schema_version", "vehicle_id", "seq"}
"""The status report's fields that :class:`VehicleStatusPublic` leaves out."""


class VehicleStatusPublic(BaseModel):
    """The vehicle's latest status report (SI units)."""

    model_config = ConfigDict(extra="forbid")

    sim_time_s: float
    line_id: str
    position_m: float
    speed_mps: float
    acceleration_mps2: float
    traction_force_n: float
    ato_state: m.AtoState
    etcs_mode: m.EtcsMode
    sc_state: m.ScState
    supervision_status: m.SupervisionStatus
    target_speed_mps: float | None
    journey_id: str | None
    position_confidence_m: float | None
    next_timing_point_id: str | None
    arrivals: list[m.ArrivalEstimate]
    vital_control: m.VitalControlStatus | None = None
    permitted_speed_mps: float | None = None
    intervention_speed_mps: float | None = None
    reference_speed_mps: float | None = None
    train_hold: bool = False
    track_data_version: str | None = Field(
        default=None, description="The track data the vehicle drives on (SHA-256 of the line)"
    )
    track_data_pending: str | None = Field(
        default=None, description="A newer version received, waiting for standstill to switch"
    )
    energy: m.EnergyStatus | None = Field(
        default=None, description="The Energy Manager's reckoning: SOC, energy to go, margin"
    )
    age_s: float | None
    rate_ok: bool


class VehiclePublic(BaseModel):
    id: str
    alive: bool
    status: VehicleStatusPublic | None
    holder: str | None = Field(default=None, description="The user holding the vehicle")
    hold_expires_at: datetime | None = Field(
        default=None, description="When the holder's lease ends unless renewed (UTC)"
    )
    simulated_operator: bool = Field(
        default=False, description="The trackside's simulated operator answers its VC requests"
    )

    @classmethod
    def from_snapshot(
        cls,
        snapshot: VehicleSnapshot,
        *,
        holder: str | None = None,
        hold_expires_at: datetime | None = None,
        simulated_operator: bool = False,
    ) -> VehiclePublic:
        report = snapshot.status
        status = None
        if report is not None:
            fields = report.model_dump(exclude=REPORT_ONLY_FIELDS, mode="python")
            status = VehicleStatusPublic(
                **fields, age_s=snapshot.status_age_s, rate_ok=snapshot.status_rate_ok
            )
        return cls(
            id=snapshot.id,
            alive=snapshot.alive,
            status=status,
            holder=holder,
            hold_expires_at=hold_expires_at,
            simulated_operator=simulated_operator,
        )


class HoldPublic(BaseModel):
    """A vehicle's hold after selecting or releasing it: the holder and their lease."""

    vehicle_id: str
    holder: str | None
    since: datetime | None = None
    expires_at: datetime | None = Field(
        default=None, description="When the lease ends unless renewed (UTC)"
    )


class CommandAckPublic(BaseModel):
    """What the vehicle answered: accepted for execution, or refused with the reason."""

    vehicle_id: str
    command_id: int
    accepted: bool
    reason: str | None

    @classmethod
    def from_ack(cls, ack: m.CommandAck) -> CommandAckPublic:
        return cls(
            vehicle_id=ack.vehicle_id,
            command_id=ack.command_id,
            accepted=ack.accepted,
            reason=ack.reason,
        )


class EmptyRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")


class TargetSpeedRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    target_speed_kmh: float = Field(ge=0.0, le=360.0, allow_inf_nan=False, description="[km/h]")


class ConfirmationKind(StrEnum):
    """Which request of the Vital Control an operator's confirmation answers (the path's
    last part: ``/vehicles/{id}/confirmations/{kind}``)."""

    EB_REARM = "eb-rearm"
    ETCS_ISOLATION = "etcs-isolation"
    ETCS_INSERTION = "etcs-insertion"
    VIGILANCE_ACK = "vigilance-ack"

    @property
    def request(self) -> m.OperatorRequestKind:
        """The kind of the VC request confirmed."""
        return _CONFIRMED_REQUESTS[self]


_CONFIRMED_REQUESTS = {
    ConfirmationKind.EB_REARM: m.OperatorRequestKind.EB_REARM,
    ConfirmationKind.ETCS_ISOLATION: m.OperatorRequestKind.ETCS_ISOLATION,
    ConfirmationKind.ETCS_INSERTION: m.OperatorRequestKind.ETCS_INSERTION,
    ConfirmationKind.VIGILANCE_ACK: m.OperatorRequestKind.VIGILANCE,
}


class ConfirmRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    number: int = Field(ge=0, le=255, description="The number of the VC request answered")


class SkipStopRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    timing_point_id: str = Field(min_length=1, max_length=64)


class TrainHoldRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    hold: bool


class JourneyProfileRequest(BaseModel):
    """Which stored journey to send, and which version (the latest when omitted)."""

    model_config = ConfigDict(extra="forbid")

    journey_id: str = Field(min_length=1, max_length=64)
    version: int | None = Field(default=None, ge=1, le=2**31 - 1)
    timeout_s: float = Field(default=5.0, gt=0.0, le=30.0, description="Wait for the JPAck [s]")


class JourneyProfileAckPublic(BaseModel):
    """What the vehicle answered: its JPAck (accepted, or rejected with the reason)."""

    journey_id: str
    version: int
    accepted: bool
    reason: str | None
    delay_s: float = Field(
        default=0.0,
        description="How much later the trackside's planner timed the journey, to keep clear "
        "of the other trains on the line [s]; the version answered is the delayed one",
    )
    conflict: str | None = Field(
        default=None, description="The conflict the journey as stored had, if the planner found one"
    )

    @classmethod
    def from_sent(cls, sent: JourneySent) -> JourneyProfileAckPublic:
        ack = sent.ack
        return cls(
            journey_id=ack.journey_id,
            version=ack.version,
            accepted=ack.accepted,
            reason=ack.reason,
            delay_s=sent.delay_s,
            conflict=None if sent.conflict is None else str(sent.conflict),
        )


class EventPublic(BaseModel):
    sim_time_s: float = Field(description="Onboard simulated time [s]")
    received_at: datetime
    severity: m.EventSeverity
    code: str
    text: str
    seq: int

    @classmethod
    def from_row(cls, row: VehicleEvent) -> EventPublic:
        return cls(
            sim_time_s=row.sim_time_s,
            received_at=row.received_at,
            severity=m.EventSeverity(row.severity),
            code=row.code,
            text=row.text,
            seq=row.seq,
        )


class TelemetryPublic(BaseModel):
    """One sample of the 1 Hz history (SI units)."""

    sim_time_s: float
    received_at: datetime
    position_m: float
    speed_mps: float
    traction_force_n: float
    reference_speed_mps: float | None
    permitted_speed_mps: float | None
    intervention_speed_mps: float | None
    ato_state: str
    etcs_mode: str
    sc_state: str
    eb: bool
    journey_id: str | None

    @classmethod
    def from_row(cls, row: TelemetrySample) -> TelemetryPublic:
        return cls.model_validate(row, from_attributes=True)


# -- lines -------------------------------------------------------------------------------------


class LinePublic(BaseModel):
    """A line's current version, summarised."""

    id: str
    name: str
    version: str = Field(description="SHA-256 of the line's canonical JSON")
    length_m: float = Field(description="Length [m]")
    ring: bool = Field(description="Chainage wraps at length_m")
    etcs_level: int

    @classmethod
    def from_summary(cls, summary: LineSummary) -> LinePublic:
        return cls(
            id=summary.id,
            name=summary.name,
            version=summary.version,
            length_m=summary.length_m,
            ring=summary.ring,
            etcs_level=summary.etcs_level,
        )


class LineVersionPublic(BaseModel):
    """One stored version of a line."""

    version: str = Field(description="SHA-256 of the line's canonical JSON")
    name: str
    length_m: float = Field(description="Length [m]")
    ring: bool
    etcs_level: int
    created_at: datetime = Field(description="When this version was first imported (UTC)")
    current: bool = Field(description="This version is the one in force")

    @classmethod
    def from_summary(cls, summary: LineSummary) -> LineVersionPublic:
        return cls(
            version=summary.version,
            name=summary.name,
            length_m=summary.length_m,
            ring=summary.ring,
            etcs_level=summary.etcs_level,
            created_at=summary.created_at,
            current=summary.current,
        )


class LineVersionRef(BaseModel):
    """A line id and its current version."""

    id: str
    version: str


class LineProfilePublic(BaseModel):
    """A line sampled for plotting; arrays of equal length, SI units."""

    id: str
    version: str
    ring: bool
    length_m: float = Field(description="Length [m]")
    chainage_m: list[float] = Field(description="Sample chainages as asked, not wrapped [m]")
    gradient_permille: list[float] = Field(description="Gradient [‰], positive uphill")
    curvature_per_m: list[float] = Field(description="Signed curvature [1/m], positive left")
    speed_limit_mps: list[float] = Field(description="Static line speed [m/s]")
    mrsp_mps: list[float] = Field(description="Most restrictive speed profile, with TSRs [m/s]")
    altitude_m: list[float] | None = Field(description="Altitude [m]; null without geodetic data")

    @classmethod
    def from_profile(cls, profile: LineProfile) -> LineProfilePublic:
        return cls(
            id=profile.line_id,
            version=profile.version,
            ring=profile.ring,
            length_m=profile.length_m,
            chainage_m=profile.chainage_m,
            gradient_permille=profile.gradient_permille,
            curvature_per_m=profile.curvature_per_m,
            speed_limit_mps=profile.speed_limit_mps,
            mrsp_mps=profile.mrsp_mps,
            altitude_m=profile.altitude_m,
        )


# -- journeys ----------------------------------------------------------------------------------


class LegPublic(BaseModel):
    index: int
    from_id: str
    to_id: str
    distance_m: float
    scheduled_s: float
    minimum_s: float
    shortfall_s: float


class JourneyCheckPublic(BaseModel):
    valid: bool
    problems: list[str]
    legs: list[LegPublic]
    line_version: str

    @classmethod
    def from_check(cls, check: JourneyCheck, line_version: str) -> JourneyCheckPublic:
        legs = [
            LegPublic(
                index=leg.index,
                from_id=leg.from_id,
                to_id=leg.to_id,
                distance_m=leg.distance_m,
                scheduled_s=leg.scheduled_s,
                minimum_s=leg.minimum_s,
                shortfall_s=leg.shortfall_s,
            )
            for leg in check.legs
        ]
        return cls(
            valid=check.valid, problems=list(check.problems), legs=legs, line_version=line_version
        )


class JourneyPublic(BaseModel):
    journey: Journey
    version: int
    line_version: str
    created_by: str

    @classmethod
    def from_stored(cls, stored: StoredJourney) -> JourneyPublic:
        return cls(
            journey=stored.journey,
            version=stored.version,
            line_version=stored.line_version,
            created_by=stored.created_by,
        )


# -- RBC ---------------------------------------------------------------------------------------


class MovementAuthorityPublic(BaseModel):
    """An MA message as sent to the vehicle, with its SvL and the vehicle's last acknowledgement."""

    movement_authority: m.MovementAuthorityMessage
    supervised_location_m: float | None = Field(
        description="Chainage of the SvL [m]; null when revoked"
    )
    acknowledgement: m.MovementAuthorityAck | None = Field(
        description="The vehicle's latest acknowledgement of any of its MAs"
    )


class SpeedRestrictionCreate(BaseModel):
    """A temporary speed restriction to put in force on the vehicle's line."""

    model_config = ConfigDict(extra="forbid")

    id: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.:-]+$")
    line_id: str = Field(min_length=1, max_length=64)
    start_m: float = Field(ge=0.0, allow_inf_nan=False, description="Start, chainage [m]")
    end_m: float = Field(gt=0.0, allow_inf_nan=False, description="End, chainage [m]")
    speed_kmh: float = Field(gt=0.0, le=360.0, allow_inf_nan=False, description="Limit [km/h]")


# -- audit -------------------------------------------------------------------------------------


class AuditPublic(BaseModel):
    id: int
    at: datetime
    user: str
    vehicle_id: str | None
    action: str
    request: dict[str, Any]
    result: AuditResult
    detail: str | None

    @classmethod
    def from_entry(cls, entry: AuditEntry) -> AuditPublic:
        return cls(
            id=entry.id,
            at=entry.at,
            user=entry.username,
            vehicle_id=entry.vehicle_id,
            action=entry.action,
            request=json.loads(entry.request),
            result=AuditResult(entry.result),
            detail=entry.detail,
        )


# -- refusals ----------------------------------------------------------------------------------


class ProblemsPublic(BaseModel):
    """Why a request was refused: a message and every problem found, with its location."""

    message: str
    problems: list[str]


class LineRejectedPublic(BaseModel):
    """The body of a 422 answer to a line import or a profile request."""

    detail: ProblemsPublic


class RefusedPublic(BaseModel):
    """The body of a refusal (409, 422)."""

    detail: ProblemsPublic
