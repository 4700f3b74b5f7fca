"""SQLAlchemy 2 models of the trackside's persistent state. Migrations: ``migrations/``."""

from __future__ import annotations

from datetime import datetime
from enum import StrEnum

from sqlalchemy import (
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    String,
    Text,
    UniqueConstraint,
    false,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

__all__ = [
    "ApiToken",
    "AuditChainHead",
    "AuditEntry",
    "Base",
    "JourneyRow",
    "RbcAuthorityRow",
    "RbcRestrictionRow",
    "Role",
    "TelemetrySample",
    "User",
    "VehicleEvent",
    "VehicleHold",
]


class Role(StrEnum):
    OBSERVER = "observer"
    DRIVER = "driver"
    ADMIN = "admin"

    @property
    def rank(self) -> int:
        return list(Role).index(self)


class Base(DeclarativeBase):
    pass


class User(Base):
    __tablename__ = "users"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    username: Mapped[str] = mapped_column(String(64), unique=True, nullable=False)
    password_hash: Mapped[str] = mapped_column(String(256), nullable=False)
    role: Mapped[str] = mapped_column(String(16), nullable=False)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)
    # A disabled user cannot log in and their tokens are refused (migration 0007).
    disabled: Mapped[bool] = mapped_column(
        Boolean, nullable=False, default=False, server_default=false()
    )


class ApiToken(Base):
    __tablename__ = "api_tokens"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    token_hash: Mapped[str] = mapped_column(String(64), unique=True, nullable=False)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"))
    issued_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)
    expires_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)
    revoked: Mapped[bool] = mapped_column(Boolean, nullable=False, default=False)


class JourneyRow(Base):
    """One version of a journey; the document is the validated ``trackdb.journey.Journey``."""

    __tablename__ = "journeys"
    __table_args__ = (UniqueConstraint("journey_id", "version", name="uq_journey_version"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    journey_id: Mapped[str] = mapped_column(String(64), nullable=False, index=True)
    version: Mapped[int] = mapped_column(Integer, nullable=False)
    line_id: Mapped[str] = mapped_column(String(64), nullable=False)
    line_version: Mapped[str] = mapped_column(String(64), nullable=False)
    document: Mapped[str] = mapped_column(Text, nullable=False)
    created_by: Mapped[str] = mapped_column(String(64), nullable=False)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)


class VehicleHold(Base):
    """Who holds a vehicle: only the holder's commands reach it (one driver at a time), until
    the lease expires."""

    __tablename__ = "vehicle_holds"

    vehicle_id: Mapped[str] = mapped_column(String(32), primary_key=True)
    username: Mapped[str] = mapped_column(String(64), nullable=False)
    since: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)
    expires_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)
    """The end of the hold's lease: renewed by the holder selecting again, by each command they
    send and while their console is connected; after it, the vehicle is free."""


class AuditEntry(Base):
    """One command or hold change: who, when, what (the request as JSON), and what came of it."""

    __tablename__ = "audit_log"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)
    username: Mapped[str] = mapped_column(String(64), nullable=False)
    vehicle_id: Mapped[str | None] = mapped_column(String(32), nullable=True, index=True)
    action: Mapped[str] = mapped_column(String(64), nullable=False)
    request: Mapped[str] = mapped_column(Text, nullable=False)
    result: Mapped[str] = mapped_column(String(16), nullable=False)
    detail: Mapped[str | None] = mapped_column(Text, nullable=True)
    prev_hash: Mapped[str | None] = mapped_column(String(64), nullable=True)
    """The previous entry's :attr:`hash` (``audit_chain.GENESIS`` for the first)."""
    hash: Mapped[str | None] = mapped_column(String(64), nullable=True)
    """SHA-256 over this entry's content and :attr:`prev_hash` (``audit_chain.entry_hash``)."""


class AuditChainHead(Base):
    """The audit chain's head: its last entry's id and hash, in one row (id 1) that every
    append locks, so that entries are chained one after another and a removed last entry shows.
    """

    __tablename__ = "audit_chain_head"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    last_id: Mapped[int | None] = mapped_column(Integer, nullable=True)
    last_hash: Mapped[str] = mapped_column(String(64), nullable=False)


class RbcAuthorityRow(Base):
    """The RBC's state for one vehicle: its MA counter and the MA in force (JSON of the
    ``MovementAuthorityMessage``; null once revoked), restored when the trackside starts."""

    __tablename__ = "rbc_movement_authorities"

    vehicle_id: Mapped[str] = mapped_column(String(32), primary_key=True)
    last_ma_id: Mapped[int] = mapped_column(Integer, nullable=False)
    message: Mapped[str | None] = mapped_column(Text, nullable=True)
    updated_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)


class RbcRestrictionRow(Base):
    """A TSR in force for one vehicle (JSON of the ``SpeedRestrictionMessage``); a revocation
    deletes its row."""

    __tablename__ = "rbc_speed_restrictions"

    vehicle_id: Mapped[str] = mapped_column(String(32), primary_key=True)
    restriction_id: Mapped[str] = mapped_column(String(64), primary_key=True)
    message: Mapped[str] = mapped_column(Text, nullable=False)
    issued_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)


class VehicleEvent(Base):
    """One onboard event, as received."""

    __tablename__ = "vehicle_events"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    vehicle_id: Mapped[str] = mapped_column(String(32), nullable=False, index=True)
    seq: Mapped[int] = mapped_column(Integer, nullable=False)
    sim_time_s: Mapped[float] = mapped_column(Float, nullable=False)
    received_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)
    severity: Mapped[str] = mapped_column(String(16), nullable=False)
    code: Mapped[str] = mapped_column(String(64), nullable=False)
    text: Mapped[str] = mapped_column(Text, nullable=False)


class TelemetrySample(Base):
    """A vehicle's status, kept once per second of its simulated time."""

    __tablename__ = "telemetry"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    vehicle_id: Mapped[str] = mapped_column(String(32), nullable=False, index=True)
    sim_time_s: Mapped[float] = mapped_column(Float, nullable=False)
    received_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), nullable=False)
    position_m: Mapped[float] = mapped_column(Float, nullable=False)
    speed_mps: Mapped[float] = mapped_column(Float, nullable=False)
    traction_force_n: Mapped[float] = mapped_column(Float, nullable=False)
    reference_speed_mps: Mapped[float | None] = mapped_column(Float, nullable=True)
    permitted_speed_mps: Mapped[float | None] = mapped_column(Float, nullable=True)
    intervention_speed_mps: Mapped[float | None] = mapped_column(Float, nullable=True)
    ato_state: Mapped[str] = mapped_column(String(16), nullable=False)
    etcs_mode: Mapped[str] = mapped_column(String(16), nullable=False)
    sc_state: Mapped[str] = mapped_column(String(16), nullable=False)
    eb: Mapped[bool] = mapped_column(Boolean, nullable=False)
    journey_id: Mapped[str | None] = mapped_column(String(64), nullable=True)
