"""Trackside settings, read from ``ATO_*`` environment variables when built in ``main()``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from protocol import DEFAULT_ROUTER_ENDPOINT, TlsFiles, ZenohSettings
from protocol.messages import OperatorRequestKind
from trackdb.headway import PlanningMode

__all__ = ["DEFAULT_WEBUI_DIR", "Settings"]

DEFAULT_WEBUI_DIR = Path(__file__).resolve().parent.parent / "webui"


class Settings(BaseSettings):
    """Everything ATO-TS needs; build it in ``main()`` and pass it to ``create_app``."""

    model_config = SettingsConfigDict(env_prefix="ATO_", extra="ignore")

    database_url: str = Field(default="sqlite:///ato.db", description="SQLAlchemy URL")
    instance_id: str = Field(default="ts1", pattern=r"^[A-Za-z0-9_-]+$")
    zenoh_mode: Literal["peer", "client"] = "client"
    zenoh_connect: tuple[str, ...] = (DEFAULT_ROUTER_ENDPOINT,)
    zenoh_listen: tuple[str, ...] = ()
    zenoh_pki_dir: Path | None = Field(
        default=None,
        description="The deployment's PKI directory (ato pki): TLS with the certificate named "
        "after instance_id; None only for an insecure, debugging set-up",
    )
    admin_user: str | None = None
    admin_password: SecretStr | None = None
    metrics_token: SecretStr | None = Field(
        default=None,
        description="Bearer token a Prometheus scrape of /metrics must carry; unset, only "
        "loopback clients may scrape (docs/metrics.md)",
    )
    token_ttl_s: float = Field(default=12 * 3600.0, gt=0, description="Bearer token life [s]")
    hold_lease_s: float = Field(
        default=60.0,
        gt=0,
        le=24 * 3600.0,
        description="A driver's hold on a vehicle lasts this long unless renewed (by selecting "
        "again, by each command, while the driver's console is connected) [s]",
    )
    webui_dir: Path = DEFAULT_WEBUI_DIR
    fleet_push_period_s: float = Field(default=0.2, gt=0, description="WebSocket push [s]")
    status_intake_period_s: float = Field(
        default=0.005,
        ge=0,
        le=0.05,
        description="The vehicles' status reports are taken in batches, at most one batch this "
        "often (each report waits at most this long; a thousand vehicles send 5 000 a second); "
        "0: each on arrival [s]",
    )
    seed_lines: bool = Field(
        default=True,
        description="At start-up, import each shipped seed line whose id is not stored yet",
    )
    rbc_scenario: Path | None = Field(
        default=None,
        description="RBC scenario script (YAML, JSON or TOML) run from start-up, on wall time",
    )
    separation_margin_m: float | None = Field(
        default=None,
        ge=0.0,
        le=10_000.0,
        description="The RBC separates the trains on a line (a moving block): each MA ends this "
        "far behind the min safe rear end of the train ahead [m]; unset: off (docs/decisions.md, "
        "'Issue 23: separation on a shared line')",
    )
    separation_extension_step_m: float = Field(
        default=50.0,
        ge=0.0,
        le=10_000.0,
        description="An MA held behind a train is extended by at least this much at a time [m]",
    )
    journey_planning: PlanningMode = Field(
        default=PlanningMode.ADJUST,
        description="With the separation on, each journey is planned against the other trains' "
        "on its line before it is sent: 'adjust' delays a conflicting one, 'check' refuses it, "
        "'off' leaves the moving block alone to keep the trains apart (docs/decisions.md, "
        "'Issue 23: journeys planned against each other')",
    )
    journey_planning_max_delay_s: float = Field(
        default=600.0,
        ge=0.0,
        le=3600.0,
        description="The longest delay the planner gives a journey; one that needs more is "
        "refused [s]",
    )

    command_timeout_s: float = Field(
        default=3.0, gt=0, le=30.0, description="Wait for a vehicle's command acknowledgement [s]"
    )
    login_max_failures: int = Field(
        default=5, ge=1, description="Failed logins per user and per address before 429"
    )
    login_window_s: float = Field(default=300.0, gt=0, description="Login failure window [s]")
    simulated_operators: Annotated[tuple[str, ...], NoDecode] = Field(
        default=(),
        description="Vehicles whose VC requests the simulated operator answers "
        "(ATO_SIMULATED_OPERATORS=URV1,URV2); no other vehicle is answered",
    )
    simulated_operator_reaction_s: float = Field(
        default=1.0, ge=0, description="Its reaction delay, in the vehicle's simulated time [s]"
    )
    simulated_operator_kinds: Annotated[tuple[OperatorRequestKind, ...], NoDecode] = Field(
        default=(OperatorRequestKind.VIGILANCE, OperatorRequestKind.EB_REARM),
        description="The requests it confirms (ETCS isolation/insertion only when listed)",
    )
    simulated_operator_thread: bool = Field(
        default=True,
        description="Step the simulated operator on a thread every 0.1 s of wall time; off, "
        "whoever embeds the service steps it (the lockstep scenario runner)",
    )
    max_body_bytes: int = Field(
        default=8 * 1024 * 1024,
        ge=1024,
        description="Largest request body [bytes], refused with 413 before authentication (a "
        "200 km line document is about 0.5 MB)",
    )
    recorder_capacity: int = Field(
        default=10_000, ge=1, description="Rows queued for the database before dropping"
    )

    @field_validator("simulated_operators", "simulated_operator_kinds", mode="before")
    @classmethod
    def _comma_separated(cls, value: Any) -> Any:
        if isinstance(value, str):
            return tuple(part.strip() for part in value.split(",") if part.strip())
        return value

    def zenoh(self) -> ZenohSettings:
        pki = self.zenoh_pki_dir
        tls = None if pki is None else TlsFiles.of(pki, self.instance_id)
        return ZenohSettings(
            mode=self.zenoh_mode, connect=self.zenoh_connect, listen=self.zenoh_listen, tls=tls
        )
