"""The KPIs of a run as one typed model: what ``kpis.json`` holds (CONTRACT.md §4 and §6).

:class:`Kpis` is what :func:`deploy.scenario.runner.run_scenario` returns in its outcome and
writes, as ``model_dump_json(indent=2)``, to ``DIR/kpis.json``; its fields are in the contract's
order (the run's identity first) and carry their unit in their description. Each structured
value has its own model (a stop, an EoA stop, an estimate's error, the NMPC's solve times, a VC
intervention, the odometry interval, a session outage, the Zenoh link's record, the wall-time
breakdown and its tasks, an action, an expectation's result).

Two kinds of run write it. A whole-stack run writes every field but the Vital Control
catalogue's (``vc_*``); a ``[vc]`` run writes the fields of :data:`VC_RUN_FIELDS`, leaving the
whole stack's out (:data:`WHOLE_STACK_FIELDS`); ``journey_reports`` is written once recorded.
Every model refuses an unknown field, and NaN or infinity (at construction and at assignment),
so ``kpis.json`` is strict JSON. Its JSON Schema is committed as
``deploy/scenario/kpis.schema.json`` (:func:`kpis_json_schema`; ``ato scenarios --kpis-schema``
prints it).
"""

from __future__ import annotations

import json
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    model_serializer,
)

__all__ = [
    "ActionRecord",
    "EnergyCertificate",
    "EoaStop",
    "EstimateError",
    "ExpectationResult",
    "FleetKpis",
    "Headway",
    "JourneyReport",
    "Kpis",
    "LegEnergy",
    "OdometryInterval",
    "ServedStop",
    "SessionOutage",
    "SolveTimes",
    "TaskWallTime",
    "TrainSummary",
    "VC_ONLY_FIELDS",
    "VC_RUN_FIELDS",
    "VcIntervention",
    "VcOutcome",
    "WHOLE_STACK_FIELDS",
    "WallTimeBreakdown",
    "ZenohLinkRecord",
    "kpis_json_schema",
]

VcOutcome = Literal["none", "eb_safe_recovery", "eb_then_decay", "decay_at_standstill"]
"""The outcome classes of a VC catalogue scenario (``deploy.bench.vc_scenarios.OutcomeClass``)."""


class _KpiModel(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_assignment=True)


class ServedStop(_KpiModel):
    """A stop the train made at a timing point of its journey."""

    name: str = Field(description="The timing point's id.")
    planned_arrival_s: float = Field(description="Planned arrival, in journey time [s].")
    arrival_error_s: float = Field(description="Actual − planned arrival [s] (negative: early).")
    stop_error_m: float = Field(
        description="Stopped true front position − stopping point, along the journey [m]."
    )
    odometry_interval_m: float = Field(
        description="ETCS's confidence interval at the stop: the larger of over- and "
        "under-reading [m]."
    )


class EoaStop(_KpiModel):
    """A standstill for an end of authority short of the journey's next stop (one an EoA)."""

    time_s: float = Field(description="When the train came to stand [s].")
    distance_to_eoa_m: float = Field(
        description="True front end to the EoA at the last standstill before it [m] "
        "(negative: passed)."
    )
    odometry_interval_m: float = Field(
        description="ETCS's confidence interval then: the larger of over- and under-reading [m]."
    )


class EstimateError(_KpiModel):
    """|estimate − true position| over the run, every 200 ms."""

    rms: float = Field(description="Root mean square [m].")
    max: float = Field(description="Largest [m].")


class SolveTimes(_KpiModel):
    """Wall time of the NMPC's solves (a wall-clock field)."""

    p50: float = Field(description="Median [ms].")
    p99: float = Field(description="99th percentile [ms].")
    max: float = Field(description="Longest [ms].")


class VcIntervention(_KpiModel):
    """An emergency brake commanded by the Vital Control."""

    cause: str = Field(description="The EB conditions (``eb1,eb3``), ``operator`` or ``vc``.")
    hazard_to_eb_command_ms: float | None = Field(
        description="From the start of the injected hazard to the EB command [ms]; null when "
        "no injected hazard precedes it."
    )
    total_to_full_eb_ms: float | None = Field(
        description="From the start of the injected hazard to the full EB [ms]; null without "
        "a hazard or a full EB."
    )


class OdometryInterval(_KpiModel):
    """ETCS's confidence interval: the larger of over- and under-reading."""

    max: float | None = Field(description="Largest over the run [m]; null without samples.")
    at_stops: list[float] = Field(description="At each stop, in the stops' order [m].")
    outside_max_m: float = Field(
        description="How far the true front end ever was outside the interval, every 10 ms [m] "
        "(0 on a sound run)."
    )


class SessionOutage(_KpiModel):
    """A loss of the established session, to the slice (200 ms)."""

    lost_s: float = Field(description="When it was lost [s].")
    reestablished_s: float | None = Field(
        description="When a session was established again [s]; null if never."
    )
    duration_s: float | None = Field(description="The outage [s]; null if never re-established.")


class ZenohLinkRecord(_KpiModel):
    """The Zenoh link fault's proxy and sessions over the run."""

    cuts: int = Field(ge=0, description="Cuts of the link by the proxy.")
    connections_dropped: int = Field(ge=0, description="TCP connections the cuts dropped.")
    flaps_on_restore: int = Field(
        ge=0, description="Losses of the sessions' contact after the link was restored."
    )


class TaskWallTime(_KpiModel):
    """One executive task's share of the stepping's wall time (a wall-clock field)."""

    releases: int = Field(ge=0, description="Times the task ran.")
    total_s: float = Field(description="Wall time in its bodies [s].")
    mean_us: float = Field(description="Mean wall time of one release [µs].")
    share: float | None = Field(
        description="Of ``lockstep_s`` [1]; null when no stepping was timed."
    )


class WallTimeBreakdown(_KpiModel):
    """Where a whole-stack run's wall time went: it measures the machine, not the run."""

    lockstep_s: float = Field(description="Wall time spent stepping the node [s].")
    tasks: dict[str, TaskWallTime] = Field(
        description="Each executive task by name, the largest total first."
    )
    executive_and_slices_s: float = Field(
        description="The rest of the stepping: the executive's own loop and the slices' "
        "bookkeeping [s]."
    )
    outside_lockstep_s: float | None = Field(
        default=None,
        description="Start-up of the trackside and the sessions, the operator's REST calls, "
        "the KPIs [s]; set once the run is over.",
    )


class ActionRecord(_KpiModel):
    """An action of the operator, the RBC or the link, as it was done."""

    action: str = Field(description="The action (``send_journey``, ``engage``, ...).")
    at_s: float = Field(description="When it was done [s].")
    accepted: bool = Field(description="Whether the vehicle (or the trackside) accepted it.")
    detail: str | None = Field(description="The answer's reason, if any.")


class JourneyReport(_KpiModel):
    """A stop the vehicle reported it would not serve."""

    stop: str = Field(description="The timing point's id.")
    reason: str = Field(description="``timing_infeasible`` or ``skipped_by_operator``.")
    at_s: float = Field(description="When it was reported [s].")


class ExpectationResult(_KpiModel):
    """An expectation of the scenario (or an invariant, or a failure of the run) judged."""

    name: str = Field(description="The expectation's name, or its text.")
    ok: bool = Field(description="Whether it held.")
    detail: str = Field(description="What was found.")


class LegEnergy(_KpiModel):
    """One leg of the journey as driven, its energies side by side (the plant's truth)."""

    stop: str = Field(description="The timing point the leg ends at.")
    departure_s: float = Field(description="When the train left its standstill [s].")
    arrival_s: float = Field(description="When it stopped at ``stop`` [s].")
    distance_m: float = Field(description="True distance run [m].")
    driven_kwh: float = Field(description="Traction energy at the wheel the plant drew [kWh].")
    plan_kwh: float = Field(
        description="Energy of the reference the ADF followed over the leg, on the onboard's "
        "model [kWh]."
    )
    optimum_kwh: float | None = Field(
        description="The offline optimum for the same distance from the same departure to the "
        "same arrival, on the plant's true parameters [kWh]; null when none was found."
    )
    driven_vs_optimum: float | None = Field(description="driven_kwh / optimum_kwh [1].")


class EnergyCertificate(_KpiModel):
    """The journey's traction energy against the best possible (docs/scenarios.md)."""

    driven_kwh: float = Field(description="Traction energy at the wheel over the legs [kWh].")
    regenerated_kwh: float | None = Field(
        description="Energy recovered by electric braking over the run [kWh]; null on a plant "
        "without electric braking (the point mass)."
    )
    plan_kwh: float = Field(description="The legs' plan energies, summed [kWh].")
    optimum_kwh: float | None = Field(
        description="The legs' offline optima, summed [kWh]; null if one is missing."
    )
    driven_vs_optimum: float | None = Field(description="driven_kwh / optimum_kwh [1].")
    plan_vs_optimum: float | None = Field(description="plan_kwh / optimum_kwh [1].")
    legs: list[LegEnergy] = Field(description="Each leg driven, in order.")


class TrainSummary(_KpiModel):
    """One train of a multi-train run: its own verdict and safety figures (its whole KPIs in
    ``{vehicle_id}/kpis.json`` beside the run's)."""

    vehicle_id: str = Field(description="The train's vehicle.")
    passed: bool = Field(description="Every expectation of the train held.")
    stops: int = Field(description="Stops it served.")
    max_stop_error_m: float | None = Field(description="Its largest |stop error| [m].")
    max_arrival_delay_s: float | None = Field(
        description="Its latest arrival against the plan [s] (negative: all early)."
    )
    eoa_stops: int = Field(description="Times it stood for an EoA short of its next stop.")
    held_s: float = Field(
        description="How long it stood for an EoA short of its next stop [s]: the delay the "
        "trains ahead (or the MAs) caused it."
    )
    max_overspeed_kmh: float = Field(description="Its true speed's largest excess [km/h].")
    etcs_sb_count: int = Field(description="ETCS service-brake interventions.")
    etcs_eb_count: int = Field(description="ETCS emergency-brake interventions.")
    vc_eb_count: int = Field(description="Vital Control emergency brakes.")
    failed: list[str] = Field(description="The expectations of the train that did not hold.")


class Headway(_KpiModel):
    """Two trains one after the other at a stop both served."""

    stop: str = Field(description="The stop.")
    ahead: str = Field(description="The train that arrived first.")
    behind: str = Field(description="The train that arrived next.")
    headway_s: float = Field(description="Between their arrivals [s].")


class FleetKpis(_KpiModel):
    """The trains of a multi-train run and how close they came (the plants' truth)."""

    trains: list[TrainSummary] = Field(description="Every train, the lead train first.")
    min_distance_m: float | None = Field(
        description="The least distance from a train's front end to the rear end of the train "
        "ahead over the run, on the truth, sampled every 0.2 s [m]; negative: they collided. "
        "Null when no train ever had one ahead."
    )
    min_distance_at_s: float | None = Field(description="When it was least [s].")
    min_distance_between: list[str] = Field(
        description="The train behind and the train ahead at that moment."
    )
    headways: list[Headway] = Field(description="Each stop's consecutive arrivals.")
    min_headway_s: float | None = Field(description="The least of the headways [s].")


class Kpis(_KpiModel):
    """The KPIs of one run: ``kpis.json`` (docs/scenarios.md, "What a run writes")."""

    scenario: str = Field(description="The scenario's name.")
    passed: bool = Field(description="Every expectation held.")
    seed: int = Field(description="The run's seed.")
    sim_time_s: float = Field(description="Simulated time [s].")
    wall_time_s: float = Field(
        description="Wall time of the run, start-up and teardown included [s] (a wall-clock field)."
    )
    real_time_factor: float = Field(
        description="sim_time_s / wall_time_s [1] (a wall-clock field)."
    )
    stops: list[ServedStop] = Field(description="The stops made, in their order.")
    max_overspeed_kmh: float = Field(
        description="Max over the run of (true speed − MRSP at the true position) [km/h]."
    )
    etcs_sb_count: int = Field(ge=0, description="ETCS service-brake interventions.")
    etcs_eb_count: int = Field(ge=0, description="ETCS emergency-brake interventions.")
    vc_eb_count: int = Field(
        ge=0, description="Emergency brakes commanded by the VC (not the power-up EB)."
    )
    system_decay: bool = Field(description="The VC ended in System Decay.")
    traction_energy_kwh: float = Field(description="Energy drawn for traction at the wheel [kWh].")
    regen_energy_kwh: float = Field(description="Energy recovered by electric braking [kWh].")
    max_jerk_mps3: float = Field(
        description="Largest |jerk| while moving, outside emergency braking [m/s³]."
    )
    ad_speed_rms_kmh: float | None = Field(
        description="RMS(v − v_ref) while the SC is in AD [km/h]; null if never in AD."
    )
    rd_speed_rms_kmh: float | None = Field(
        description="RMS(v − v_ref) while the SC is in RD, departure included [km/h]; null if "
        "never in RD."
    )
    max_switch_du_frac: float | None = Field(
        description="Max |u(t+) − u(t−)| at SC mode switches / (u_max − u_min) [1]; null "
        "without a switch."
    )
    position_error_m: EstimateError = Field(
        description="|fused position − true position| [m]: the position the ATO-OB drives on."
    )
    nmpc_ms: SolveTimes | None = Field(
        description="Wall time of the NMPC solves [ms]; null without a solve."
    )
    nmpc_failures: int = Field(ge=0, description="NMPC solves that failed into the fallback.")
    nmpc_fallback_s: float = Field(description="Simulated time driven on the fallback [s].")
    vc_interventions: list[VcIntervention] = Field(
        description="Each EB the VC commanded, timed from its hazard."
    )
    vc_outcome: VcOutcome | None = Field(
        default=None, description="``[vc]`` runs: the outcome class the scenario ended in."
    )
    vc_expected_outcome: VcOutcome | None = Field(
        default=None, description="``[vc]`` runs: the catalogue's expected outcome class."
    )
    vc_decay_reasons: list[str] | None = Field(
        default=None, description="``[vc]`` runs: why the VC went to System Decay."
    )
    max_wheel_slip_mps: float | None = Field(
        default=None,
        description="Largest |ω·r − v| of the two wheelsets [m/s]; null on the point mass.",
    )
    etcs_estimate_error_m: EstimateError | None = Field(
        default=None,
        description="|ETCS's estimated front end − true front end| [m]; null without it.",
    )
    soc_end: float | None = Field(
        default=None, description="Battery state of charge at the end [1]; null without one."
    )
    soc_min: float | None = Field(default=None, description="Least state of charge [1].")
    soc_min_time_s: float | None = Field(
        default=None, description="When the state of charge was least [s]."
    )
    soc_min_time_from_cruise_s: float | None = Field(
        default=None,
        description="soc_min_time_s from the cruise's start (the speed first within 1 km/h of "
        "the run's highest reference) [s]; null without a cruise.",
    )
    range_extender_kw_after_soc_min: float | None = Field(
        default=None,
        description="The range extender's mean power from 120 s after the SOC's minimum [kW].",
    )
    odometry_interval_m: OdometryInterval | None = Field(
        default=None, description="ETCS's confidence interval [m]; null without it."
    )
    min_eoa_margin_m: float | None = Field(
        default=None,
        description="Least distance from the true front end to the ETCS EoA [m] (negative: "
        "passed); null without an EoA.",
    )
    eoa_stops: list[EoaStop] = Field(description="Each standstill for an EoA (one an EoA).")
    max_speed_over_cap_kmh: float | None = Field(
        default=None,
        description="Most the true speed exceeded the journey's cap while in AD, 0 if never "
        "[km/h]; null without a cap.",
    )
    min_obstacle_margin_m: float | None = Field(
        default=None,
        description="Least distance from the true front end to the obstacle [m] (negative: "
        "reached); null without one.",
    )
    sensor_lost_s: dict[str, float] | None = Field(
        default=None,
        description="When the localisation first reported each sensor not alive, by sensor [s].",
    )
    odometer_failure_detection_s: float | None = Field(
        default=None,
        description="From the first odometer fault to that report [s]; null without both.",
    )
    lockstep_barrier_misses: int | None = Field(
        default=None, ge=0, description="Lockstep barriers missed; null when paced."
    )
    lockstep_report_retransmissions: int | None = Field(
        default=None, ge=0, description="Status reports sent again in lockstep; null when paced."
    )
    session_losses: int | None = Field(
        default=None, ge=0, description="Established sessions the vehicle lost."
    )
    sessions_established: int | None = Field(
        default=None, ge=0, description="Sessions the trackside accepted."
    )
    session_outages: list[SessionOutage] | None = Field(
        default=None, description="Each loss of an established session."
    )
    fallback_stops: int | None = Field(
        default=None, ge=0, description="Fallback stops the ATO-OB completed."
    )
    zenoh_link: ZenohLinkRecord | None = Field(
        default=None, description="The Zenoh link fault's record; null without one."
    )
    wall_time_breakdown: WallTimeBreakdown | None = Field(
        default=None, description="Where the wall time went (a wall-clock field)."
    )
    actions: list[ActionRecord] | None = Field(
        default=None, description="Each action with its time and the vehicle's answer."
    )
    energy: EnergyCertificate | None = Field(
        default=None,
        description="The journey's energy certificate: driven, plan and optimum; null without "
        "a journey driven.",
    )
    energy_plan_fallbacks: int | None = Field(
        default=None,
        ge=0,
        description="Legs of the journey planned without the energy optimiser (the plain "
        "LSPB); null without a journey.",
    )
    journey_reports: list[JourneyReport] | None = Field(
        default=None,
        description="Stops the vehicle reported it would not serve; written once recorded.",
    )
    fleet: FleetKpis | None = Field(
        default=None,
        description="A multi-train run's trains, their least distance and headways; the "
        "other fields are the lead train's. Written in multi-train runs only.",
    )
    expectations: list[ExpectationResult] = Field(
        description="The scenario's expectations, its invariants and the run's failures, judged."
    )

    @model_serializer(mode="wrap")
    def _leave_out_the_other_kind(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        """The fields of the run's kind only: a ``[vc]`` run has no whole-stack fields, a
        whole-stack run no ``vc_*`` ones (and no ``journey_reports`` until they are recorded)."""
        data: dict[str, Any] = handler(self)
        left_out = WHOLE_STACK_FIELDS if self.vc_outcome is not None else ()
        left_out += tuple(name for name in _LEFT_OUT_WHEN_NULL if getattr(self, name) is None)
        for name in left_out:
            data.pop(name, None)
        return data


VC_ONLY_FIELDS = ("vc_outcome", "vc_expected_outcome", "vc_decay_reasons")
"""Fields of ``[vc]`` runs only."""
_LEFT_OUT_WHEN_NULL = (*VC_ONLY_FIELDS, "journey_reports", "fleet")
WHOLE_STACK_FIELDS = tuple(
    name
    for name, field in Kpis.model_fields.items()
    if field.default is None and name not in _LEFT_OUT_WHEN_NULL
)
"""Fields of whole-stack runs only (a ``[vc]`` run leaves them out): those with a default."""
VC_RUN_FIELDS = tuple(
    name
    for name in Kpis.model_fields
    if name not in WHOLE_STACK_FIELDS + ("journey_reports", "fleet")
)
"""The fields a ``[vc]`` run writes."""


def kpis_json_schema() -> str:
    """The JSON Schema of ``kpis.json``: pretty-printed, keys sorted, with a final newline.

    ``deploy/scenario/kpis.schema.json`` holds this text; regenerate it with
    ``ato scenarios --kpis-schema > deploy/scenario/kpis.schema.json`` after changing the models.
    """
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema"} | Kpis.model_json_schema()
    return json.dumps(schema, indent=2, sort_keys=True, ensure_ascii=False) + "\n"
