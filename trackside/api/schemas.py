"""Response and request bodies of the REST API (``XPublic`` for what is returned)."""

from __future__ import annotations

from datetime import datetime

from pydantic import BaseModel, ConfigDict, Field

from protocol import messages as m
from trackdb.storage import LineSummary
from trackside.bridge import VehicleSnapshot
from trackside.services.lines import LineProfile

__all__ = [
    "LinePublic",
    "LineProfilePublic",
    "LineRejectedPublic",
    "LineVersionPublic",
    "LineVersionRef",
    "ProblemsPublic",
    "TokenPublic",
    "VehiclePublic",
    "VehicleStatusPublic",
]


class TokenPublic(BaseModel):
    access_token: str
    token_type: str = "bearer"


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
    age_s: float | None
    rate_ok: bool


class VehiclePublic(BaseModel):
    id: str
    alive: bool
    status: VehicleStatusPublic | None
    holder: str | None = Field(default=None, description="The user holding the vehicle")
    simulated_operator: bool = Field(
        default=False, description="The trackside's simulated operator answers its VC requests"
    )

    @classmethod
    def from_snapshot(
        cls,
        snapshot: VehicleSnapshot,
        *,
        holder: str | None = None,
        simulated_operator: bool = False,
    ) -> VehiclePublic:
        report = snapshot.status
        status = None
        if report is not None:
            fields = report.model_dump(
                exclude={"schema_version", "vehicle_id", "seq"}, mode="python"
            )
            status = VehicleStatusPublic(
                **fields, age_s=snapshot.status_age_s, rate_ok=snapshot.status_rate_ok
            )
        return cls(
            id=snapshot.id,
            alive=snapshot.alive,
            status=status,
            holder=holder,
            simulated_operator=simulated_operator,
        )


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


class ProblemsPublic(BaseModel):
    """Why a request was refused: a message and every problem found, with its location."""

    message: str
    problems: list[str]


class LineRejectedPublic(BaseModel):
    """The body of a 422 answer to a line import or a profile request."""

    detail: ProblemsPublic
