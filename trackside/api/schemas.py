"""Response and request bodies of the REST API (``XPublic`` for what is returned)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from protocol import messages as m
from trackside.bridge import VehicleSnapshot

__all__ = ["TokenPublic", "VehiclePublic", "VehicleStatusPublic"]


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
    age_s: float | None
    rate_ok: bool


class VehiclePublic(BaseModel):
    id: str
    alive: bool
    status: VehicleStatusPublic | None

    @classmethod
    def from_snapshot(cls, snapshot: VehicleSnapshot) -> VehiclePublic:
        report = snapshot.status
        status = None
        if report is not None:
            fields = report.model_dump(
                exclude={"schema_version", "vehicle_id", "seq"}, mode="python"
            )
            status = VehicleStatusPublic(
                **fields, age_s=snapshot.status_age_s, rate_ok=snapshot.status_rate_ok
            )
        return cls(id=snapshot.id, alive=snapshot.alive, status=status)
