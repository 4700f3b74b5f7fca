"""The outcome of a run: its KPIs (``kpis.json``, CONTRACT.md §4), its telemetry, its verdict.

:func:`build_outcome` reads a finished whole-stack run (the node's counters, the telemetry
recorder's samples and records, the run's log) into its :class:`~deploy.scenario.kpi_model.Kpis`
and checks the scenario's expectations and invariants on them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from deploy.scenario.energy_certificate import OptimumProfile, run_energy
from deploy.scenario.invariants import invariant_expectations
from deploy.scenario.kpi_model import (
    ActionRecord,
    ExpectationResult,
    Kpis,
    ServedStop,
    SessionOutage,
    TaskWallTime,
    WallTimeBreakdown,
    ZenohLinkRecord,
)
from deploy.scenario.kpis import (
    RunCounters,
    check_expectations,
    compute_kpis,
    odometry_interval_kpi,
)
from deploy.scenario.run_context import RunContext
from deploy.scenario.schema import OdometerFailure, ScenarioSpec, SensorDropout
from deploy.scenario.zenoh_link import ZenohLinkFault
from onboard.ato_ob.transitions import Trigger
from onboard.runtime import TaskStats
from protocol.units import MPS_PER_KMH

__all__ = ["RunOutcome", "build_outcome", "judge"]


@dataclass
class RunOutcome:
    kpis: Kpis
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    optimum_profiles: tuple[OptimumProfile, ...] = ()
    """Each leg's offline optimum, for the report (``deploy.scenario.energy_certificate``)."""
    trains: dict[str, RunOutcome] = field(default_factory=dict)
    """A multi-train run: the other trains' outcomes by vehicle id (this one is the lead's)."""

    @property
    def passed(self) -> bool:
        return self.kpis.passed


def build_outcome(ctx: RunContext, link: ZenohLinkFault | None) -> RunOutcome:
    """The KPIs of the finished run, its expectations checked, with its telemetry."""
    node, recorder = ctx.node, ctx.recorder
    columns = recorder.arrays()
    train = compute_kpis(
        columns,
        stops=[
            ServedStop(
                name=stop.name,
                planned_arrival_s=stop.planned_arrival_s,
                arrival_error_s=stop.arrival_s - stop.planned_arrival_s,
                stop_error_m=stop.stop_error_m,
                odometry_interval_m=stop.odometry_interval_m,
            )
            for stop in recorder.stops
        ],
        counters=_counters(ctx),
        position_errors_m=columns["estimated_position_m"] - columns["position_m"],
        vc_interventions=recorder.vc_interventions,
    )
    energy = run_energy(ctx, columns)
    kpis = Kpis(
        **train,
        **_run_kpis(ctx, link),
        odometry_interval_m=odometry_interval_kpi(
            columns,
            [stop.odometry_interval_m for stop in recorder.stops],
            outside_m=recorder.maxima.outside_interval_m,
        ),
        wall_time_breakdown=_wall_time_breakdown(node.executive.stats, ctx.lockstep_wall_s),
        actions=[ActionRecord(**vars(item)) for item in ctx.actions],
        energy=energy.certificate,
        energy_plan_fallbacks=energy.fallbacks,
        # The verdict is judge's, the wall clock run_scenario's once the run is over.
        passed=False,
        expectations=[],
        wall_time_s=0.0,
        real_time_factor=0.0,
    )
    failures = [ExpectationResult(name=text, ok=False, detail=text) for text in ctx.failures]
    judge(kpis, ctx.spec, failures)
    return RunOutcome(kpis, columns, energy.profiles)


def judge(kpis: Kpis, spec: ScenarioSpec, failures: Sequence[ExpectationResult] = ()) -> None:
    """Set the run's ``expectations`` (the scenario's, the run's ``failures``, the invariants
    when the scenario asks for them) and ``passed``, every one held."""
    expectations = check_expectations(kpis, spec.expect) + list(failures)
    if spec.invariants is not None:
        expectations += invariant_expectations(spec, kpis)
    kpis.expectations = expectations
    kpis.passed = all(item.ok for item in expectations)


def _counters(ctx: RunContext) -> RunCounters:
    stack, plant, recorder = ctx.node.stack, ctx.node.plant, ctx.recorder
    low, high = plant.force_limits_n(0.0)
    return RunCounters(
        etcs_sb_count=stack.etcs.service_brake_interventions,
        etcs_eb_count=stack.etcs.emergency_brake_interventions,
        vc_eb_count=recorder.maxima.vc_eb_count,
        system_decay=stack.vital is not None and stack.vital.outputs.system_decay,
        traction_energy_j=plant.traction_energy_j,
        regen_energy_j=float(getattr(plant, "regen_energy_j", 0.0)),
        max_overspeed_mps=max(recorder.maxima.overspeed_mps, 0.0),
        nmpc_solve_times_s=stack.driving.nmpc.stats.solve_times_s,
        nmpc_failures=stack.driving.nmpc.stats.failures,
        nmpc_step_s=stack.driving.nmpc.config.step_s,
        force_range_n=high - low,
    )


def _run_kpis(ctx: RunContext, link: ZenohLinkFault | None) -> dict[str, Any]:
    """The run's identity, its margins and the sessions' and the link's record: fields of
    :class:`Kpis` by name."""
    node, recorder, fast = ctx.node, ctx.recorder, ctx.options.fast
    return {
        "scenario": ctx.spec.name,
        "seed": ctx.seed,
        "sim_time_s": node.clock.now_s,
        "min_eoa_margin_m": _finite(recorder.maxima.eoa_margin_m),
        "eoa_stops": [record.as_kpi() for record in recorder.eoa_stops],
        "max_speed_over_cap_kmh": (
            None
            if recorder.cap_mps is None
            else max(recorder.maxima.over_cap_mps, 0.0) / MPS_PER_KMH
        ),
        "min_obstacle_margin_m": _finite(recorder.maxima.obstacle_margin_m),
        "sensor_lost_s": dict(recorder.sensor_lost_s),
        "odometer_failure_detection_s": _odometer_detection_s(ctx),
        "lockstep_barrier_misses": node.barrier_misses if fast else None,
        "lockstep_report_retransmissions": node.report_retransmissions if fast else None,
        "session_losses": node.session_client.counters.lost,
        "sessions_established": node.session_client.counters.accepted,
        "session_outages": [SessionOutage(**outage) for outage in ctx.session_outages],
        "fallback_stops": sum(
            1
            for t in node.stack.controller.transitions
            if t.trigger is Trigger.FALLBACK_STOP_COMPLETED
        ),
        "zenoh_link": None
        if link is None
        else ZenohLinkRecord(
            cuts=link.proxy.stats().cuts,
            connections_dropped=link.connections_dropped,
            flaps_on_restore=link.flaps,
        ),
    }


def _odometer_detection_s(ctx: RunContext) -> float | None:
    """From the first odometer fault to the localisation reporting it, if both happened."""
    starts = [
        f.start_s
        for f in ctx.spec.faults
        if isinstance(f, OdometerFailure)
        or (isinstance(f, SensorDropout) and f.sensor == "odometer")
    ]
    lost = ctx.recorder.sensor_lost_s.get("odometer")
    if not starts or lost is None:
        return None
    return round(lost - min(starts), 3)


def _wall_time_breakdown(stats: Mapping[str, TaskStats], lockstep_s: float) -> WallTimeBreakdown:
    """Where the wall time of the stepping went: each task's bodies, and the rest (the
    executive's own work and the slices' bookkeeping), largest first. A wall-clock field."""
    tasks = sorted(stats.items(), key=lambda item: item[1].exec_total_ns, reverse=True)
    in_tasks_s = sum(task.exec_total_ns for _, task in tasks) / 1e9
    return WallTimeBreakdown(
        lockstep_s=round(lockstep_s, 3),
        tasks={
            name: TaskWallTime(
                releases=task.releases,
                total_s=round(task.exec_total_ns / 1e9, 3),
                mean_us=round(task.exec_mean_ns / 1e3, 1),
                share=round(task.exec_total_ns / 1e9 / lockstep_s, 4) if lockstep_s else None,
            )
            for name, task in tasks
        },
        executive_and_slices_s=round(lockstep_s - in_tasks_s, 3),
    )


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None
