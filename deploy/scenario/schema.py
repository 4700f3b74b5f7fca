"""The scenario file (TOML, ``deploy/scenarios/``): what a run sets up, does and expects.

A scenario names the line, the vehicle and its plant fidelity, the journey, the operator's
actions, the faults to inject and the expectations on the KPIs of ``kpis.json``
(CONTRACT.md §4). Units are SI unless the name says otherwise (``speed_kmh``). Every model
forbids unknown keys, so a misspelt key is an error with its line, not a silent default.

Actions run in file order: each waits for its time (``at_s``: simulated time; ``after_s``:
since the previous action) and its condition (``when``), then does one thing through the
remote driver's API, as an operator at the console would.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from deploy.scenario.conditions import Condition, parse_condition
from trackdb.headway import PlanningMode
from trackdb.journey import JourneyTimingPoint
from trackdb.railjson import DEFAULT_LINE_SPEED_KMH

__all__ = [
    "Action",
    "Expectation",
    "Fault",
    "InvariantSettings",
    "JourneySpec",
    "LineImportSpec",
    "OperatorSpec",
    "ScenarioSpec",
    "SeparationSpec",
    "TrainSpec",
    "VcCatalogueSpec",
    "VehicleSpec",
]

Seconds = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


LineId = Annotated[str, Field(pattern=r"^[A-Za-z0-9_-]{1,64}$")]


class LineImportSpec(_Model):
    """How a line is built from the RailJSON infrastructure of ``line_file``: the options of
    ``ato trackdb import --format railjson`` (``from``, ``to``, ``via``: operational points)."""

    model_config = ConfigDict(
        extra="forbid", frozen=True, validate_by_name=True, serialize_by_alias=True
    )

    format: Literal["railjson"]
    from_op: str = Field(alias="from", min_length=1, max_length=255)
    """The operational point the line starts at (its chainage 0)."""
    to_op: str = Field(alias="to", min_length=1, max_length=255)
    """The operational point the line ends at."""
    via: tuple[Annotated[str, Field(min_length=1, max_length=255)], ...] = Field(
        default=(), max_length=100
    )
    """Operational points the path passes, in order."""
    id: LineId
    """The line's id."""
    name: str | None = Field(default=None, min_length=1, max_length=128)
    default_speed_kmh: float = Field(
        default=DEFAULT_LINE_SPEED_KMH, gt=0.0, le=540.0, allow_inf_nan=False
    )
    """The line speed where no speed section applies [km/h]."""
    speed_tag: str | None = Field(default=None, min_length=1, max_length=255)
    """Speed sections' limits for this tag where they have one (their default elsewhere)."""


class VehicleSpec(_Model):
    id: str = Field(default="URV1", pattern=r"^[A-Za-z0-9_-]{1,32}$")
    fidelity: Literal["point_mass", "bogie"] = "point_mass"
    start_position_m: float = Field(default=0.0, ge=0.0, allow_inf_nan=False)
    initial_soc: float = Field(default=0.9, gt=0.0, le=1.0, description="Bogie only: battery SOC")
    range_extender_kw: float | None = Field(default=None, ge=0.0, le=1000.0, allow_inf_nan=False)
    """Bogie only: the range extender's rated power [kW] when not the URV's 100 (0: out of
    service)."""
    vc_replicas: Literal[1, 2] = 2
    """Two VC boards in 2-out-of-2 with the voter and watchdog, as on the seeds' vehicle; 1 for a
    single board (for comparisons)."""
    vc_datalog: bool = True
    """Record the VC's datalog (``vc-datalog.jsonl`` in the report directory, if any)."""
    energy_plans: bool = True


class OperatorSpec(_Model):
    simulated: bool = True
    """A simulated operator answers the Vital Control's vigilance and EB-rearm requests."""
    reaction_s: float = Field(default=1.0, ge=0.0, le=60.0, allow_inf_nan=False)
    reengage: bool = False
    """The operator engages ATO again, ``reaction_s`` after it stands ready (RE) once the journey
    has been engaged: after a fallback stop (a lost session, an ATO failure), as an operator at
    the console does. Generated scenarios with such faults set it; their actions cannot, since
    the fault may end with the train already at a stop."""


class JourneySpec(_Model):
    """The journey the operator sends; it starts where the vehicle stands when sent."""

    id: str = Field(pattern=r"^[A-Za-z0-9_.-]{1,64}$")
    max_speed_kmh: float | None = Field(default=None, gt=0.0, le=540.0, allow_inf_nan=False)
    timing_points: tuple[JourneyTimingPoint, ...] = Field(min_length=1, max_length=500)


ActionKind = Literal[
    "rd_target_speed",
    "send_journey",
    "engage",
    "disengage",
    "emergency_brake",
    "confirm_rearm",
    "isolate_etcs",
    "insert_etcs",
    "issue_ma",
    "see_event",
]


class Action(_Model):
    """One operator action: when, and what."""

    do: ActionKind
    at_s: Seconds | None = None
    """Not before this simulated time [s]."""
    after_s: Seconds | None = None
    """Not before this long after the previous action [s]."""
    when: str | None = None
    """A condition on the vehicle's state (see ``deploy.scenario.conditions``)."""
    speed_kmh: float | None = Field(default=None, ge=0.0, le=360.0, allow_inf_nan=False)
    end_of_authority_m: float | None = Field(default=None, ge=0.0, allow_inf_nan=False)
    """``issue_ma``: the RBC (REST, admin) issues an MA from the vehicle to this chainage [m]."""
    event: str | None = Field(default=None, pattern=r"^[a-z0-9_.]{1,64}$")
    """``see_event``: the operator finds an event of this code in the vehicle's event log at
    the trackside (the run fails if it is not there)."""
    timeout_s: Seconds = 3600.0
    """The run fails if the action has not happened this long after it was armed [s]."""

    @field_validator("when")
    @classmethod
    def _condition(cls, when: str | None) -> str | None:
        if when is not None:
            parse_condition(when)  # raises ValueError with the reason
        return when

    @model_validator(mode="after")
    def _consistent(self) -> Action:
        if (self.do == "rd_target_speed") != (self.speed_kmh is not None):
            raise ValueError("speed_kmh goes with rd_target_speed, and only with it")
        if (self.do == "issue_ma") != (self.end_of_authority_m is not None):
            raise ValueError("end_of_authority_m goes with issue_ma, and only with it")
        if (self.do == "see_event") != (self.event is not None):
            raise ValueError("event goes with see_event, and only with it")
        return self

    @property
    def condition(self) -> Condition | None:
        return None if self.when is None else parse_condition(self.when)


class _Window(_Model):
    start_s: Seconds
    end_s: float = Field(default=float("inf"), gt=0.0)

    @model_validator(mode="after")
    def _ordered(self) -> _Window:
        if self.end_s <= self.start_s:
            raise ValueError("end_s must be after start_s")
        return self


class SensorDropout(_Window):
    kind: Literal["sensor_dropout"]
    sensor: Literal["imu", "odometer", "gps"]


class OdometerFailure(_Window):
    kind: Literal["odometer_failure"]
    mode: Literal["silent", "stuck_zero"] = "silent"


class UdpLinkFault(_Window):
    kind: Literal["udp_link"]
    loss: float = Field(default=0.0, ge=0.0, le=1.0)
    reorder: float = Field(default=0.0, ge=0.0, le=1.0)
    duplicate: float = Field(default=0.0, ge=0.0, le=1.0)
    corrupt: float = Field(default=0.0, ge=0.0, le=1.0)


class ZenohLinkLoss(_Window):
    """The onboard ↔ trackside Zenoh link is lost in the window (``deploy.scenario.link_proxy``):
    ``silent``, a link gone quiet that each side notices by its lease; ``reset``, connections
    torn down at once."""

    kind: Literal["zenoh_link_loss"]
    mode: Literal["silent", "reset"] = "silent"


class AtoFailure(_Window):
    kind: Literal["ato_failure"]


class VigilanceAbsent(_Window):
    kind: Literal["vigilance_absent"]


class RelayFault(_Window):
    kind: Literal["relay_fault"]


class TachometerFault(_Window):
    kind: Literal["tachometer"]
    mode: Literal["frozen", "noisy", "silent"]


class FrictionDrop(_Window):
    kind: Literal["friction_drop"]
    factor: float = Field(gt=0.0, le=1.0, description="Adhesion multiplied by this")


class WheelDiameterError(_Model):
    """The wheels' real diameter differs from the calibrated one for the whole run (wear): the
    axle-end sensors read ``error`` long (calibrated / real − 1; +0.02 reads 2 % long)."""

    kind: Literal["wheel_diameter"]
    error: float = Field(gt=-0.05, lt=0.05, allow_inf_nan=False)


class BaliseMissed(_Model):
    """The BTM fails to read these balise groups (NID_BG) whenever the train passes them."""

    kind: Literal["balise_missed"]
    balise_group_ids: tuple[int, ...] = Field(min_length=1, max_length=64)


class Obstacle(_Model):
    kind: Literal["obstacle"]
    at_s: Seconds
    position_m: float = Field(ge=0.0, allow_inf_nan=False, description="Chainage [m]")


class _Triggered(_Model):
    """A one-shot fault injected once ``at_s`` has come and ``when`` holds (either may be left
    out, not both): ``when`` places it exactly relative to the train (``next_stop == tp2-south
    and position_m >= 2600``)."""

    at_s: Seconds | None = None
    """Not before this simulated time [s]."""
    when: str | None = None
    """A condition on the vehicle's state (see ``deploy.scenario.conditions``)."""

    @field_validator("when")
    @classmethod
    def _condition(cls, when: str | None) -> str | None:
        if when is not None:
            parse_condition(when)
        return when

    @model_validator(mode="after")
    def _triggered(self) -> _Triggered:
        if self.at_s is None and self.when is None:
            raise ValueError("give at_s, when, or both")
        return self

    @property
    def condition(self) -> Condition | None:
        return None if self.when is None else parse_condition(self.when)


SHORTENED_DANGER_POINT_M = 50.0
"""D_DP of a shortened MA's new end unless the fault gives one [m]: an RBC shortens an MA to a
signal or a marker board, with a danger point beyond it (docs/scenarios.md)."""


class ShortenedAuthority(_Triggered):
    kind: Literal["ma_shortened"]
    end_of_authority_m: float = Field(ge=0.0, allow_inf_nan=False, description="Chainage [m]")
    danger_point_m: float = Field(
        default=SHORTENED_DANGER_POINT_M,
        ge=0.0,
        le=1000.0,
        allow_inf_nan=False,
        description="D_DP: from the new EoA to its danger point [m]; 0 for none (SvL = EoA)",
    )


class TemporarySpeedRestriction(_Triggered):
    kind: Literal["tsr"]
    start_m: float = Field(ge=0.0, allow_inf_nan=False)
    end_m: float = Field(gt=0.0, allow_inf_nan=False)
    speed_kmh: float = Field(gt=0.0, le=360.0, allow_inf_nan=False)


class TracksideRestart(_Model):
    kind: Literal["trackside_restart"]
    at_s: Seconds
    down_s: float = Field(default=5.0, gt=0.0, le=600.0)


Fault = Annotated[
    SensorDropout
    | OdometerFailure
    | UdpLinkFault
    | ZenohLinkLoss
    | AtoFailure
    | VigilanceAbsent
    | RelayFault
    | TachometerFault
    | FrictionDrop
    | Obstacle
    | ShortenedAuthority
    | TemporarySpeedRestriction
    | TracksideRestart
    | WheelDiameterError
    | BaliseMissed,
    Field(discriminator="kind"),
]


class Expectation(_Model):
    """A KPI of ``kpis.json`` compared with a value: ``stops.stop_error_m abs<= 0.5`` holds
    when it holds for every stop."""

    kpi: str = Field(min_length=1, max_length=80, pattern=r"^[a-z_]+(\.[a-z_0-9]+)*$")
    op: Literal["<=", "<", ">=", ">", "==", "!=", "abs<="]
    value: float | bool | str
    name: str | None = None


InvariantName = Literal[
    "overspeed_mrsp",
    "overspeed_cap",
    "eoa_passed",
    "eoa_stop_far",
    "etcs_intervention",
    "vc_eb",
    "stop_missed",
    "nmpc_unbounded",
    "crash",
]
"""The invariants of ``deploy.scenario.invariants``."""


class InvariantSettings(_Model):
    """The invariants of ``deploy.scenario.invariants`` judged on the run's KPIs, each violation
    a failed expectation (generated scenarios carry them, so that ``ato run FILE`` judges a run
    as the campaign did)."""

    max_stop_error_m: float = Field(default=0.5, gt=0.0, le=100.0, allow_inf_nan=False)
    """A journey stop is served when the train stands this close to it [m]."""
    max_eoa_stop_m: float = Field(default=10.0, gt=0.0, le=1000.0, allow_inf_nan=False)
    """Standing for an EoA short of its next stop, the train closes up this near to it [m]."""
    overspeed_tolerance_kmh: float = Field(default=0.0, ge=0.0, le=10.0, allow_inf_nan=False)
    """How far above the MRSP or the journey's cap the true speed may go [km/h]."""
    nmpc_max_fallback_s: float = Field(default=2.0, ge=0.0, allow_inf_nan=False)
    """How long the NMPC's fallback law may drive in a run [s]: a solve that fails (no feasible
    iterate within the iteration caps) hands one control step to it."""
    nmpc_max_ms: float | None = Field(default=None, gt=0.0, allow_inf_nan=False)
    """The longest NMPC solve allowed [ms, wall time]; not judged when absent. The solve is
    bounded by construction (iteration caps); a wall-time bound holds only on an idle machine
    (a campaign's workers share the cores, and a preempted solve counts the wait)."""
    vigilance_answer_s: float = Field(default=10.0, gt=0.0, allow_inf_nan=False)
    """An operator unseen this long (reaction included) misses a vigilance request [s]: an
    absent operator or a lost link that long asks for the VC's EB."""
    skip: tuple[InvariantName, ...] = ()
    """Invariants not judged (by name)."""


class VcCatalogueSpec(_Model):
    """Run one scenario of the Vital Control catalogue (``deploy.bench.vc_catalogue``) instead of
    the whole stack: the VC with its emulated I/O on the catalogue's scripted train."""

    catalogue: str = Field(min_length=1, max_length=40)
    replicas: Literal[1, 2] = 1


class TrainSpec(_Model):
    """Another train on the scenario's line (``[[trains]]``): its vehicle, its operator, its
    journey and actions, and the expectations on its own KPIs. It runs in the same lockstep
    run as the scenario's own vehicle, on the same trackside; faults stay the lead train's."""

    vehicle: VehicleSpec
    operator: OperatorSpec = OperatorSpec()
    journey: JourneySpec | None = None
    actions: tuple[Action, ...] = ()
    expect: tuple[Expectation, ...] = ()

    @model_validator(mode="after")
    def _consistent(self) -> TrainSpec:
        if any(a.do == "send_journey" for a in self.actions) and self.journey is None:
            raise ValueError("a send_journey action needs a [trains.journey]")
        return self


class SeparationSpec(_Model):
    """The RBC's separation of the trains on the line (``trackside.separation``: a moving
    block): each MA ends ``margin_m`` behind the min safe rear end of the train ahead."""

    margin_m: float = Field(gt=0.0, le=10_000.0, allow_inf_nan=False)
    extension_step_m: float = Field(default=50.0, ge=0.0, le=10_000.0, allow_inf_nan=False)
    plan_journeys: PlanningMode = PlanningMode.OFF
    """The trackside's planning of the journeys against each other (``trackside.journey_planner``):
    off unless asked for, so that a scenario can run trains into each other's MAs; the service's
    default is ``adjust``."""


MULTI_TRAIN_FAULTS_REFUSED = ("trackside_restart", "zenoh_link_loss")
"""Faults a multi-train run does not inject: they act on the one trackside and link all the
trains share."""


class ScenarioSpec(_Model):
    """One scenario file."""

    name: str = Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
    title: str = Field(min_length=1, max_length=200)
    line: LineId | None = None
    """A stored line: built in, or in the run's database (``deploy.scenario.line_source``)."""
    line_file: str | None = Field(default=None, min_length=1, max_length=4096)
    """A line document, relative to the scenario file: our JSON, or RailJSON with
    ``[line_import]``."""
    line_import: LineImportSpec | None = None
    seed: int = Field(default=0, ge=0, lt=2**32)
    duration_s: float = Field(gt=0.0, le=100_000.0, description="Simulated time at most [s]")
    end_when: str | None = None
    """Stop early when this condition holds (e.g. the end of the journey)."""
    vehicle: VehicleSpec = VehicleSpec()
    operator: OperatorSpec = OperatorSpec()
    journey: JourneySpec | None = None
    actions: tuple[Action, ...] = ()
    faults: tuple[Fault, ...] = ()
    expect: tuple[Expectation, ...] = ()
    vc: VcCatalogueSpec | None = None
    invariants: InvariantSettings | None = None
    trains: tuple[TrainSpec, ...] = Field(default=(), max_length=9)
    """The other trains on the line, behind or ahead of the scenario's vehicle (the lead
    train): a multi-train run (``deploy.scenario.fleet``)."""
    separation: SeparationSpec | None = None

    @field_validator("end_when")
    @classmethod
    def _condition(cls, end_when: str | None) -> str | None:
        if end_when is not None:
            parse_condition(end_when)
        return end_when

    @model_validator(mode="after")
    def _consistent(self) -> ScenarioSpec:
        if (self.line is None) == (self.line_file is None):
            raise ValueError("name the line with line or with line_file, one of the two")
        if self.line_import is not None and self.line_file is None:
            raise ValueError("[line_import] goes with line_file, and only with it")
        if any(a.do == "send_journey" for a in self.actions) and self.journey is None:
            raise ValueError("a send_journey action needs a [journey]")
        if self.trains:
            self._check_trains()
        return self

    def _check_trains(self) -> None:
        ids = [self.vehicle.id, *(train.vehicle.id for train in self.trains)]
        if len(set(ids)) != len(ids):
            raise ValueError(f"each train has its own vehicle id: {ids}")
        if self.separation is None:
            raise ValueError("[[trains]] share the line under the RBC's [separation]: set it")
        if self.vc is not None:
            raise ValueError("[[trains]] run the whole stack, not a [vc] catalogue scenario")
        refused = sorted({f.kind for f in self.faults} & set(MULTI_TRAIN_FAULTS_REFUSED))
        if refused:
            raise ValueError(f"faults not injected in a multi-train run: {refused}")
