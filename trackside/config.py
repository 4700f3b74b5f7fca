"""Trackside settings, read from ``ATO_*`` environment variables when built in ``main()``."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, SecretStr
from pydantic_settings import BaseSettings, SettingsConfigDict

from protocol import DEFAULT_ROUTER_ENDPOINT, ZenohSettings

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
    admin_user: str | None = None
    admin_password: SecretStr | None = None
    token_ttl_s: float = Field(default=12 * 3600.0, gt=0, description="Bearer token life [s]")
    webui_dir: Path = DEFAULT_WEBUI_DIR
    fleet_push_period_s: float = Field(default=0.2, gt=0, description="WebSocket push [s]")
    seed_lines: bool = Field(
        default=True,
        description="At start-up, import each shipped seed line whose id is not stored yet",
    )
    rbc_scenario: Path | None = Field(
        default=None,
        description="RBC scenario script (YAML, JSON or TOML) run from start-up, on wall time",
    )

    def zenoh(self) -> ZenohSettings:
        return ZenohSettings(
            mode=self.zenoh_mode, connect=self.zenoh_connect, listen=self.zenoh_listen
        )
