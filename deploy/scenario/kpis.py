"""The KPIs of a run (``kpis.json``, CONTRACT.md §4) and the check of a scenario's expectations.

:func:`compute_kpis` turns a run's telemetry, stops and counters into the train's fields of
:class:`~deploy.scenario.kpi_model.Kpis`; :func:`check_expectations` compares a run's
:class:`Kpis` with the scenario's ``[[expect]]`` entries. A KPI path names a field as
``kpis.json`` writes it: a key (``max_overspeed_kmh``), a key and a member
(``position_error_m.rms``), or a list and a member of its items (``stops.stop_error_m``: the
expectation holds when it holds for every stop; ``stops.count`` is the list's length). The
verdict and the wall time (``passed``, ``expectations``, ``wall_time_s``,
``real_time_factor``) are not judged: they are set after the check.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from deploy.scenario.kpi_model import (
    EstimateError,
    ExpectationResult,
    Kpis,
    OdometryInterval,
    ServedStop,
    SolveTimes,
    VcIntervention,
)
from deploy.scenario.schema import Expectation
from deploy.stats import percentiles
from protocol.units import J_PER_KWH, MPS_PER_KMH

__all__ = [
    "JERK_MIN_SPEED_MPS",
    "NOT_JUDGED",
    "RunCounters",
    "check_expectations",
    "compute_kpis",
    "kpi_value",
    "odometry_interval_kpi",
]

JERK_MIN_SPEED_MPS = 0.2
"""Jerk is measured while moving (the instant of stopping excluded), as the ADF's tests do."""


@dataclass(frozen=True, kw_only=True)
class RunCounters:
    """What the run counted besides its telemetry."""

    etcs_sb_count: int
    etcs_eb_count: int
    vc_eb_count: int
    system_decay: bool
    traction_energy_j: float
    regen_energy_j: float
    max_overspeed_mps: float
    nmpc_solve_times_s: Sequence[float]
    nmpc_failures: int
    """Solves that failed into the fallback law, each for one control step."""
    nmpc_step_s: float
    force_range_n: float
    """u_max − u_min of the vehicle, for the switch jump's fraction [N]."""


def _rms(values: np.ndarray) -> float | None:
    return None if values.size == 0 else float(np.sqrt(np.mean(values**2)))


def _speed_rms_kmh(columns: Mapping[str, np.ndarray], state: str) -> float | None:
    mask = (columns["sc_state"] == state) & np.isfinite(columns["reference_speed_mps"])
    error = columns["speed_mps"][mask] - columns["reference_speed_mps"][mask]
    rms = _rms(error)
    return None if rms is None else rms / MPS_PER_KMH


def _max_jerk(columns: Mapping[str, np.ndarray]) -> float:
    times, accelerations = columns["time_s"], columns["acceleration_mps2"]
    if times.size < 2:
        return 0.0
    jerk = np.diff(accelerations) / np.diff(times)
    speeds, eb = columns["speed_mps"], columns["vc_eb"] > 0
    moving = (speeds[1:] > JERK_MIN_SPEED_MPS) & (speeds[:-1] > JERK_MIN_SPEED_MPS)
    calm = moving & ~eb[1:] & ~eb[:-1]
    return float(np.abs(jerk[calm]).max()) if calm.any() else 0.0


def _max_switch_fraction(columns: Mapping[str, np.ndarray], force_range_n: float) -> float | None:
    states, demand = columns["sc_state"], columns["force_demand_n"]
    switches = np.nonzero(states[1:] != states[:-1])[0]
    driving = {"AD", "RD", "HRD2AD", "HAD2RD"}
    jumps = [
        abs(float(demand[k + 1] - demand[k]))
        for k in switches
        if states[k] in driving and states[k + 1] in driving
    ]
    return max(jumps) / force_range_n if jumps else None


def _percentiles_ms(samples: Sequence[float]) -> SolveTimes | None:
    if not samples:
        return None
    values = np.asarray(samples) * 1000.0
    p50, p99 = percentiles(values, (50, 99))
    return SolveTimes(p50=p50, p99=p99, max=float(values.max()))


def compute_kpis(
    columns: Mapping[str, np.ndarray],
    *,
    stops: Sequence[ServedStop],
    counters: RunCounters,
    position_errors_m: np.ndarray,
    vc_interventions: Sequence[VcIntervention],
) -> dict[str, Any]:
    """The train's fields of :class:`Kpis` by name (the run's identity, its margins, its
    record and its verdict are the outcome's, the wall-clock fields the runner's)."""
    errors = np.abs(position_errors_m[np.isfinite(position_errors_m)])
    return {
        "stops": list(stops),
        "max_overspeed_kmh": counters.max_overspeed_mps / MPS_PER_KMH,
        "etcs_sb_count": counters.etcs_sb_count,
        "etcs_eb_count": counters.etcs_eb_count,
        "vc_eb_count": counters.vc_eb_count,
        "system_decay": counters.system_decay,
        "traction_energy_kwh": counters.traction_energy_j / J_PER_KWH,
        "regen_energy_kwh": counters.regen_energy_j / J_PER_KWH,
        "max_jerk_mps3": _max_jerk(columns),
        "ad_speed_rms_kmh": _speed_rms_kmh(columns, "AD"),
        "rd_speed_rms_kmh": _speed_rms_kmh(columns, "RD"),
        "max_switch_du_frac": _max_switch_fraction(columns, counters.force_range_n),
        "position_error_m": _error_stats(errors),
        "nmpc_ms": _percentiles_ms(counters.nmpc_solve_times_s),
        "nmpc_failures": counters.nmpc_failures,
        "nmpc_fallback_s": counters.nmpc_failures * counters.nmpc_step_s,
        "vc_interventions": list(vc_interventions),
        "max_wheel_slip_mps": _finite_max(columns.get("wheel_slip_mps")),
        "etcs_estimate_error_m": _error_kpi(columns, "etcs_position_m"),
        **_energy_kpis(columns),
    }


def _error_stats(errors: np.ndarray) -> EstimateError:
    """{rms, max} of finite absolute errors [m]; 0 without any."""
    return EstimateError(rms=_rms(errors) or 0.0, max=float(errors.max()) if errors.size else 0.0)


def _error_kpi(columns: Mapping[str, np.ndarray], estimate: str) -> EstimateError | None:
    """{rms, max} of |estimate − true position| [m]; None without the column."""
    if estimate not in columns:
        return None
    errors = np.abs(columns[estimate] - columns["position_m"])
    return _error_stats(errors[np.isfinite(errors)])


def odometry_interval_kpi(
    columns: Mapping[str, np.ndarray], at_stops_m: Sequence[float], *, outside_m: float
) -> OdometryInterval | None:
    """ETCS's confidence interval [m]: its max over the run, at each stop, and how far the true
    front end ever was outside it (``outside_max_m``, 0 when it never was)."""
    values = columns.get("odometry_interval_m")
    if values is None:
        return None
    return OdometryInterval(
        max=_finite_max(values),
        at_stops=[float(v) for v in at_stops_m],
        outside_max_m=max(outside_m, 0.0),
    )


def _finite_max(values: np.ndarray | None) -> float | None:
    """The largest finite value, or None when there is none (a column the plant lacks)."""
    if values is None:
        return None
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else None


RANGE_EXTENDER_SETTLE_S = 120.0
"""The range extender's power is averaged from this long after the SOC's minimum [s]."""
CRUISE_TOLERANCE_MPS = 1.0 * MPS_PER_KMH
"""The cruise starts when the speed first comes this close to the run's highest reference."""


def _cruise_start_time_s(columns: Mapping[str, np.ndarray]) -> float | None:
    """When the speed first reaches the run's highest reference speed less 1 km/h [s]."""
    references = columns["reference_speed_mps"]
    finite = np.isfinite(references)
    if not finite.any():
        return None
    reached = columns["speed_mps"] >= references[finite].max() - CRUISE_TOLERANCE_MPS
    return float(columns["time_s"][np.argmax(reached)]) if reached.any() else None


def _energy_kpis(columns: Mapping[str, np.ndarray]) -> dict[str, float | None]:
    """Seed 003 §7: the SOC's minimum and when (from the start, and from the cruise's start,
    as the seed's missions start at speed), the range extender's power after it, the SOC at
    the end; None on plants without a powertrain."""
    soc, times = columns["soc"], columns["time_s"]
    if soc.size == 0 or not np.isfinite(soc).all():
        return {
            "soc_end": None,
            "soc_min": None,
            "soc_min_time_s": None,
            "soc_min_time_from_cruise_s": None,
            "range_extender_kw_after_soc_min": None,
        }
    lowest = int(np.argmin(soc))
    after = times > times[lowest] + RANGE_EXTENDER_SETTLE_S
    extender = columns["range_extender_kw"][after]
    cruise_s = _cruise_start_time_s(columns)
    return {
        "soc_end": float(soc[-1]),
        "soc_min": float(soc[lowest]),
        "soc_min_time_s": float(times[lowest]),
        "soc_min_time_from_cruise_s": None if cruise_s is None else float(times[lowest]) - cruise_s,
        "range_extender_kw_after_soc_min": float(extender.mean()) if extender.size else None,
    }


NOT_JUDGED = frozenset({"passed", "expectations", "wall_time_s", "real_time_factor"})
"""Fields an expectation cannot name: the verdict, and the wall time (set after the check)."""


def kpi_value(kpis: Kpis, path: str) -> Any:
    """The value at ``path``; a list's member gives the list of its items' values.

    Raises
    ------
    KeyError
        ``path`` names no KPI of the run.
    """
    return _value_at(_judged_fields(kpis), path)


def _judged_fields(kpis: Kpis) -> dict[str, Any]:
    """The run's KPIs as ``kpis.json`` writes them, but the fields not judged."""
    return kpis.model_dump(exclude=set(NOT_JUDGED))


def _value_at(kpis: Mapping[str, Any], path: str) -> Any:
    head, _, rest = path.partition(".")
    if head not in kpis:
        raise KeyError(f"no KPI {head!r}")
    value = kpis[head]
    if not rest:
        return value
    if isinstance(value, list):
        if rest == "count":
            return len(value)
        return [_member(item, rest, path) for item in value]
    if isinstance(value, Mapping):
        return _member(value, rest, path)
    raise KeyError(f"{head} has no member {rest!r}")


def _member(value: Mapping[str, Any], rest: str, path: str) -> Any:
    """``rest`` of a KPI's table (a dotted path again: ``fleet.trains.passed``)."""
    if rest in value:
        return value[rest]
    head = rest.partition(".")[0]
    if "." in rest and head in value:
        return _value_at(value, rest)
    raise KeyError(f"no KPI {path!r}")


def _holds(value: Any, op: str, expected: Any) -> bool:
    if value is None:
        return False
    if isinstance(value, list):
        # An expectation on every stop holds on no stop at all only vacuously: it fails.
        return bool(value) and all(_holds(item, op, expected) for item in value)
    if op == "abs<=":
        return bool(abs(value) <= expected)
    if isinstance(value, float) and math.isnan(value):
        return False
    comparisons = {
        "<=": value <= expected,
        "<": value < expected,
        ">=": value >= expected,
        ">": value > expected,
        "==": value == expected,
        "!=": value != expected,
    }
    return bool(comparisons[op])


def check_expectations(kpis: Kpis, expectations: Sequence[Expectation]) -> list[ExpectationResult]:
    """Each expectation with whether it holds and what was found."""
    fields = _judged_fields(kpis)
    results = []
    for expectation in expectations:
        name = expectation.name or f"{expectation.kpi} {expectation.op} {expectation.value}"
        try:
            value = _value_at(fields, expectation.kpi)
        except KeyError as exc:
            results.append(ExpectationResult(name=name, ok=False, detail=str(exc.args[0])))
            continue
        ok = _holds(value, expectation.op, expectation.value)
        results.append(ExpectationResult(name=name, ok=ok, detail=f"found {value!r}"))
    return results
