"""The space a scenario generator draws from (TOML, ``deploy/spaces/``), and its loader.

A space names the line and where the vehicle starts, and gives a range ``[low, high]`` for
every drawn value: the journey (legs, speed cap, timing slack per leg, dwells), the operator's
reaction time, TSRs and MA shortenings placed relative to the train, sensor and link faults
with their windows. It also holds the invariants' thresholds that the generated scenarios carry
(``[invariants]``), and the values the shrinker moves towards (``[shrink_to]``: the library's).
Unknown keys are errors; a range whose low end lies above its high end is one too.
``deploy.scenario.generate`` draws from it; docs/scenarios.md describes every key.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Annotated, Literal, get_args

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, model_validator

from deploy._exceptions import DeployError
from deploy.scenario.line_source import ScenarioLineError, stored_line
from deploy.scenario.schema import InvariantSettings, VehicleSpec

__all__ = [
    "DEFAULT_SPACE",
    "FaultKindSpace",
    "GeneratorSpace",
    "MaSpace",
    "SpaceFileError",
    "TsrSpace",
    "load_space",
]

DEFAULT_SPACE = Path(__file__).resolve().parent.parent / "spaces" / "ring.toml"
"""The space ``ato campaign --generate`` draws from without ``--space``."""


def _ordered(value: tuple[float, float]) -> tuple[float, float]:
    if value[0] > value[1]:
        raise ValueError(f"a range is [low, high] with low <= high, not {list(value)}")
    return value


Interval = Annotated[tuple[float, float], AfterValidator(_ordered)]
"""[low, high], drawn uniformly."""
Count = Annotated[tuple[int, int], AfterValidator(_ordered)]
"""[fewest, most], drawn uniformly."""
Share = Annotated[float, Field(ge=0.0, le=1.0)]
Weight = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _within(name: str, value: tuple[float, float], low: float, high: float) -> None:
    if value[0] < low or value[1] > high:
        raise ValueError(f"{name} must lie within [{low:g}, {high:g}], not {list(value)}")


TsrPlacement = Literal["ahead", "inside_leg", "braking_point"]
MaPlacement = Literal["before", "beyond"]


class TsrSpace(_Model):
    """Temporary speed restrictions, each in a leg of the journey."""

    count: Count = (0, 2)
    length_m: Interval = (100.0, 400.0)
    speed_kmh: Interval = (15.0, 40.0)
    placement: dict[TsrPlacement, Weight] = Field(
        default_factory=lambda: dict.fromkeys(get_args(TsrPlacement), 1.0)
    )
    """How the TSR comes into force: ``ahead`` once the previous stop is served (before the
    leg's departure), ``inside_leg`` while the train runs in the leg well before it,
    ``braking_point`` with the train just short of the point where it must start braking."""
    braking_point_margin_m: Interval = (0.0, 50.0)
    """How far short of the braking point the train is when the TSR comes into force [m]."""

    @model_validator(mode="after")
    def _valid(self) -> TsrSpace:
        _within("tsr.length_m", self.length_m, 10.0, 5000.0)
        _within("tsr.speed_kmh", self.speed_kmh, 5.0, 200.0)
        if self.count[0] < 0 or self.count[1] > 10:
            raise ValueError("tsr.count must lie within [0, 10]")
        if self.count[1] > 0 and sum(self.placement.values()) <= 0.0:
            raise ValueError("tsr.placement needs a positive weight")
        return self


class MaSpace(_Model):
    """MA shortenings, each in a leg, to before or beyond the leg's stop."""

    count: Count = (0, 1)
    placement: dict[MaPlacement, Weight] = Field(
        default_factory=lambda: dict.fromkeys(get_args(MaPlacement), 1.0)
    )
    before_m: Interval = (30.0, 300.0)
    """``before``: the new EoA lies this far short of the stop [m]."""
    beyond_m: Interval = (20.0, 200.0)
    """``beyond``: the new EoA lies this far past the stop [m]."""

    @model_validator(mode="after")
    def _valid(self) -> MaSpace:
        _within("ma.before_m", self.before_m, 1.0, 5000.0)
        _within("ma.beyond_m", self.beyond_m, 1.0, 5000.0)
        if self.count[0] < 0 or self.count[1] > 10:
            raise ValueError("ma.count must lie within [0, 10]")
        if self.count[1] > 0 and sum(self.placement.values()) <= 0.0:
            raise ValueError("ma.placement needs a positive weight")
        return self


FaultKind = Literal[
    "sensor_dropout",
    "odometer_failure",
    "udp_link",
    "zenoh_link_loss",
    "vigilance_absent",
    "ato_failure",
]


class FaultKindSpace(_Model):
    weight: Weight = 1.0
    window_s: Interval = (5.0, 60.0)
    """How long the fault lasts [s]; it starts at a time drawn over the journey."""
    rate: Interval = (0.05, 0.3)
    """``udp_link`` only: each of loss, reorder, duplicate and corrupt is drawn from it."""

    @model_validator(mode="after")
    def _valid(self) -> FaultKindSpace:
        if self.window_s[0] <= 0.0:
            raise ValueError(f"window_s must be positive, not {list(self.window_s)}")
        _within("rate", self.rate, 0.0, 1.0)
        return self


class FaultSpace(_Model):
    count: Count = (0, 0)
    kinds: dict[FaultKind, FaultKindSpace] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _valid(self) -> FaultSpace:
        if self.count[0] < 0 or self.count[1] > 10:
            raise ValueError("faults.count must lie within [0, 10]")
        if self.count[1] > 0 and sum(k.weight for k in self.kinds.values()) <= 0.0:
            raise ValueError("faults.kinds needs a kind with a positive weight")
        return self


class ShrinkTargets(_Model):
    """Where the shrinker moves values: the library's (bologna-ring's field test)."""

    cap_kmh: float = Field(default=40.0, gt=0.0)
    slack: float = Field(default=0.4, gt=-1.0)
    dwell_s: float = Field(default=20.0, ge=0.0)
    reaction_s: float = Field(default=1.0, ge=0.0)


class GeneratorSpace(_Model):
    """One space file."""

    name: str = Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
    line: str = Field(pattern=r"^[A-Za-z0-9_-]{1,64}$")
    start_position_m: tuple[float, ...] = Field(default=(0.0,), min_length=1)
    """Where the vehicle may stand at power-up (chainage) [m]: it drives in SR from there to
    the first balise group that brings FS, stops, and the journey starts where it stands."""
    vehicle: VehicleSpec = VehicleSpec()
    legs: Count = (1, 3)
    """Journey legs (stops) [count]."""
    skip_platform: Share = 0.2
    """Chance that a leg runs past the next platform to the one after."""
    cap_kmh: Interval = (20.0, 80.0)
    """The journey's speed cap [km/h]."""
    slack: Interval = (-0.05, 0.40)
    """Each leg's scheduled running time over its plain LSPB time, less one [1]."""
    dwell_s: Interval = (10.0, 40.0)
    reaction_s: Interval = (0.5, 5.0)
    """The simulated operator's reaction time [s]."""
    duration_margin_s: float = Field(default=400.0, gt=0.0)
    """Simulated time allowed after the journey's last scheduled arrival [s]."""
    tsr: TsrSpace = TsrSpace()
    ma: MaSpace = MaSpace()
    faults: FaultSpace = FaultSpace()
    invariants: InvariantSettings = InvariantSettings()
    shrink_to: ShrinkTargets = ShrinkTargets()

    @model_validator(mode="after")
    def _valid(self) -> GeneratorSpace:
        try:
            line = stored_line(self.line)
        except ScenarioLineError as exc:
            raise ValueError(f"line: {exc}") from exc
        if not line.stopping_points:
            raise ValueError(f"line {self.line!r} has no stopping points")
        for start in self.start_position_m:
            if not 0.0 <= start < line.length_m:
                raise ValueError(f"start_position_m {start} lies off the line")
        if self.legs[0] < 1 or self.legs[1] > 20:
            raise ValueError(f"legs must lie within [1, 20], not {list(self.legs)}")
        _within("cap_kmh", self.cap_kmh, 5.0, 300.0)
        _within("slack", self.slack, -0.5, 5.0)
        _within("dwell_s", self.dwell_s, 0.0, 3600.0)
        _within("reaction_s", self.reaction_s, 0.0, 60.0)
        return self


class SpaceFileError(DeployError, ValueError):
    """A space file that cannot be used: which, where in it, and why."""


def load_space(path: str | Path | None = None) -> GeneratorSpace:
    """The space in ``path`` (the default space without one)."""
    path = Path(path) if path is not None else DEFAULT_SPACE
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise SpaceFileError(f"{path}: cannot read it: {exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise SpaceFileError(f"{path}: TOML: {exc}") from exc
    try:
        return GeneratorSpace.model_validate(data)
    except ValidationError as exc:
        error = exc.errors()[0]
        where = ".".join(str(part) for part in error["loc"]) or "the file"
        message = error["msg"].removeprefix("Value error, ")
        raise SpaceFileError(f"{path}: {where}: {message}") from exc
