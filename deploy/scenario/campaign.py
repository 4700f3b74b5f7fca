"""``ato campaign``: a matrix of scenarios × seeds × fault parameters over worker processes.

Each cell is one lockstep run of :func:`deploy.scenario.runner.run_scenario` in a worker
process (its own Zenoh sessions, its own trackside database). A variation ``KEY=V1,V2`` sets a
field of the scenario by its dotted path (``faults.0.at_s=100,150``) before the run, so a fault
can be swept; the matrix is the product of the scenarios, the seeds and every variation.

The summary counts the passes and the unsafe outcomes of each scenario and gives the
distribution (median, p99, max) of its headline KPIs. A run is unsafe when the train went
faster than the ETCS intervention allows (overspeed above the MRSP beyond dV_ebi), passed its
end of authority, or reached an obstacle; a run that raised is a crash. Both are listed by cell.
"""

from __future__ import annotations

import collections
import contextlib
import itertools
import json
import math
import multiprocessing
import os
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from deploy.scenario.kpi_model import Kpis, ServedStop
from deploy.scenario.loader import load_scenario, parse_scenario
from deploy.scenario.runner import RunOptions, run_scenario
from deploy.scenario.schema import ScenarioSpec
from deploy.stats import percentiles
from onboard.etcs import dv_ebi_mps
from protocol.units import MPS_PER_KMH

__all__ = [
    "FAULT_SCENARIOS",
    "Cell",
    "CellResult",
    "PartialSummary",
    "Variation",
    "distribution",
    "parse_variation",
    "run_campaign",
    "summarise",
]

FAULT_SCENARIOS = (
    "ma-shortened",
    "obstacle",
    "vigilance-absent",
    "ato-failure",
    "tsr",
    "trackside-restart",
    "zenoh-link-loss",
    "gps-outage",
    "odometer-failure",
    "udp-loss",
    "wheel-slip",
    "slide-at-stop",
    "odometer-drift",
    "balise-missed",
)
"""The whole-stack fault scenarios: the campaign's default matrix."""
STOP_KPIS: dict[str, Callable[[ServedStop], float]] = {
    "stop_error_m": lambda stop: stop.stop_error_m,
    "arrival_error_s": lambda stop: stop.arrival_error_s,
}
"""Per stop: their absolute values over every stop of a scenario's runs are distributed."""
HEADLINE_KPIS: dict[str, Callable[[Kpis], float | None]] = {
    "max_overspeed_kmh": lambda kpis: kpis.max_overspeed_kmh,
    "ad_speed_rms_kmh": lambda kpis: kpis.ad_speed_rms_kmh,
    "position_error_m.rms": lambda kpis: kpis.position_error_m.rms,
    "min_eoa_margin_m": lambda kpis: kpis.min_eoa_margin_m,
    "traction_energy_kwh": lambda kpis: kpis.traction_energy_kwh,
    "real_time_factor": lambda kpis: kpis.real_time_factor,
}
"""Per run, by their path in ``kpis.json`` (the summary's keys)."""


@dataclass(frozen=True)
class Variation:
    path: str
    values: tuple[Any, ...]


def parse_variation(text: str) -> Variation:
    """``faults.0.at_s=100,150`` → the path and its values (numbers where they parse)."""
    path, sep, values = text.partition("=")
    if not sep or not path or not values:
        raise ValueError(f"a variation is KEY=V1,V2,...; got {text!r}")
    parsed: list[Any] = []
    for value in values.split(","):
        try:
            parsed.append(int(value) if value.lstrip("-").isdigit() else float(value))
        except ValueError:
            parsed.append({"true": True, "false": False}.get(value, value))
    return Variation(path.strip(), tuple(parsed))


@dataclass(frozen=True)
class Cell:
    scenario: str
    seed: int
    setting: tuple[tuple[str, Any], ...] = ()

    @property
    def label(self) -> str:
        extra = "".join(f" {path}={value}" for path, value in self.setting)
        return f"{self.scenario} seed={self.seed}{extra}"


@dataclass(frozen=True)
class CellResult:
    cell: Cell
    kpis: Kpis | None
    error: str | None = None

    @property
    def crashed(self) -> bool:
        return self.kpis is None

    @property
    def unsafe(self) -> list[str]:
        """What made the run unsafe, if anything."""
        if self.kpis is None:
            return []
        kpis, found = self.kpis, []
        over = kpis.max_overspeed_kmh
        if over > 0.0 and over * MPS_PER_KMH > _ebi_margin_mps():
            found.append(f"overspeed {over:.2f} km/h beyond the EBI")
        eoa = kpis.min_eoa_margin_m
        if eoa is not None and eoa < 0.0:
            found.append(f"EoA passed by {-eoa:.2f} m")
        obstacle = kpis.min_obstacle_margin_m
        if obstacle is not None and obstacle < 0.0:
            found.append(f"obstacle reached ({-obstacle:.2f} m beyond)")
        return found


def _ebi_margin_mps() -> float:
    """dV_ebi at low speed: the smallest overspeed at which ETCS would brake [m/s]."""
    return dv_ebi_mps(0.0)


def apply_setting(spec: ScenarioSpec, setting: Sequence[tuple[str, Any]]) -> ScenarioSpec:
    """``spec`` with each dotted path set to its value, validated again.

    Raises
    ------
    ValueError
        A path that names nothing in the scenario, or a value the scenario refuses.
    """
    data = _lists(spec.model_dump(mode="python"))
    for path, value in setting:
        target: Any = data
        *parents, last = path.split(".")
        try:
            for part in parents:
                target = target[int(part)] if isinstance(target, list) else target[part]
            if isinstance(target, list):
                target[int(last)] = value
            elif isinstance(target, dict) and last in target:
                target[last] = value
            else:
                raise KeyError(last)
        except (KeyError, IndexError, ValueError, TypeError) as exc:
            raise ValueError(f"{spec.name}: {path} names nothing in the scenario") from exc
    return ScenarioSpec.model_validate(data)


def _lists(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _lists(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_lists(v) for v in value]
    return value


def run_cell(cell: Cell, text: str | None = None) -> CellResult:
    """One run (in a worker process); an exception becomes a crash with its traceback.

    ``text`` is the scenario file's content when the worker may not have the file (a worker of
    a cluster on another machine); the cell's scenario is then only its name and path."""
    try:
        scenario = (
            load_scenario(cell.scenario)
            if text is None
            else parse_scenario(text, path=cell.scenario, base_dir=Path(cell.scenario).parent)
        )
        spec = apply_setting(scenario, cell.setting)
        outcome = run_scenario(spec, RunOptions(fast=True, seed=cell.seed))
    except Exception:
        return CellResult(cell, None, traceback.format_exc(limit=8))
    return CellResult(cell, outcome.kpis)


def matrix(
    scenarios: Sequence[str], seeds: Iterable[int], variations: Sequence[Variation] = ()
) -> list[Cell]:
    settings = [
        tuple(zip((v.path for v in variations), combination, strict=True))
        for combination in itertools.product(*(v.values for v in variations))
    ]
    return [
        Cell(name, seed, setting) for name in scenarios for seed in seeds for setting in settings
    ]


RUNS_PER_WORKER = 4
"""A worker process is replaced after this many runs: each whole-stack run leaves some 45 MB
behind in its process (a 280-run campaign grew its two workers to 5 GB each), and a new
worker's imports cost about 3 s. (``ProcessPoolExecutor``'s own ``max_tasks_per_child`` hangs
on Python 3.11 once a worker is replaced, so each slot recycles its own one-process pool.)"""


def run_campaign(
    cells: Sequence[Cell], *, workers: int, on_result: Callable[[CellResult], None] | None = None
) -> list[CellResult]:
    """Every cell over ``workers`` processes; the results in the cells' order.

    Each of ``workers`` slots takes the next cell and runs it in its worker process, a new one
    every :data:`RUNS_PER_WORKER` runs. A worker that dies (a crash of native code) costs its
    cell, which is a crash, and the slot goes on with a new worker.
    """
    pending = collections.deque(enumerate(cells))
    results: dict[int, CellResult] = {}
    lock = threading.Lock()

    def slot() -> None:
        while pending:
            # Spawned, not forked: a fork copies a process whose Zenoh runtime threads it does
            # not copy (a test run, a console that has opened sessions); its sessions hang.
            with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
                for _ in range(RUNS_PER_WORKER):
                    try:
                        index, cell = pending.popleft()
                    except IndexError:
                        return
                    died = False
                    try:
                        result = pool.submit(run_cell, cell).result()
                    except BrokenProcessPool as exc:
                        result, died = CellResult(cell, None, f"the worker died: {exc}"), True
                    with lock:
                        results[index] = result
                        if on_result is not None:
                            on_result(result)
                    if died:
                        break

    threads = [threading.Thread(target=slot, daemon=True) for _ in range(max(1, workers))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return [results[index] for index in range(len(cells))]


def _stop_values(kpis: Kpis | None, key: str) -> list[float]:
    """``key`` of every stop the run made (none for a crash)."""
    if kpis is None:
        return []
    value = STOP_KPIS[key]
    return [value(stop) for stop in kpis.stops]


def distribution(values: list[float]) -> dict[str, float] | None:
    finite = np.asarray([v for v in values if math.isfinite(v)])
    if finite.size == 0:
        return None
    median, p99 = percentiles(finite, (50, 99))
    return {"median": median, "p99": p99, "max": float(finite.max())}


def summarise(results: Sequence[CellResult]) -> dict[str, Any]:
    """The JSON summary: per scenario, the counts and the KPI distributions; and the cells."""
    by_scenario: dict[str, list[CellResult]] = {}
    for result in results:
        by_scenario.setdefault(result.cell.scenario, []).append(result)
    scenarios = {}
    for name, group in by_scenario.items():
        ran = [r for r in group if r.kpis is not None]
        scenarios[name] = {
            "runs": len(group),
            "passed": sum(1 for r in ran if r.kpis is not None and r.kpis.passed),
            "failed": sum(1 for r in ran if r.kpis is not None and not r.kpis.passed),
            "crashed": len(group) - len(ran),
            "unsafe": sum(1 for r in ran if r.unsafe),
            "kpis": {
                path: distribution(
                    [v for r in ran if r.kpis is not None and (v := value(r.kpis)) is not None]
                )
                for path, value in HEADLINE_KPIS.items()
            }
            | {
                f"stops.{key}.abs": distribution(
                    [abs(v) for r in ran for v in _stop_values(r.kpis, key)]
                )
                for key in STOP_KPIS
            },
        }
    return {
        "runs": len(results),
        "passed": sum(s["passed"] for s in scenarios.values()),
        "crashed": sum(s["crashed"] for s in scenarios.values()),
        "unsafe": sum(s["unsafe"] for s in scenarios.values()),
        "scenarios": scenarios,
        "cells": [
            {
                "label": r.cell.label,
                "scenario": r.cell.scenario,
                "seed": r.cell.seed,
                "setting": dict(r.cell.setting),
                "passed": None if r.kpis is None else r.kpis.passed,
                "unsafe": r.unsafe,
                "error": r.error,
                "failed_expectations": []
                if r.kpis is None
                else [e.name for e in r.kpis.expectations if not e.ok],
                "stops": {key: _stop_values(r.kpis, key) for key in STOP_KPIS},
            }
            for r in results
        ],
    }


def write_summary(summary: dict[str, Any], path: Path) -> None:
    """Write ``summary`` to ``path`` through a temporary file renamed over it: a campaign
    interrupted while writing leaves the previous summary, never half of one."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as out:
            out.write(json.dumps(summary, indent=2, allow_nan=False))
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise


class PartialSummary:
    """The summary of the runs ended so far, written to ``path`` as they end, so that an
    interrupted campaign leaves the summary of what it ran.

    Written on the first result, then at most every ``interval_s`` (a summary of 10⁴ runs takes
    a noticeable time to make) and on the last; ``pending`` counts the runs not ended yet.
    """

    def __init__(self, cells: Sequence[Cell], path: Path, *, interval_s: float = 5.0) -> None:
        self.path = path
        self.interval_s = interval_s
        self._total = len(cells)
        self._order: dict[Cell, collections.deque[int]] = {}
        for index, cell in enumerate(cells):
            self._order.setdefault(cell, collections.deque()).append(index)
        self._done: dict[int, CellResult] = {}
        self._written_at = -math.inf

    def add(self, result: CellResult) -> None:
        self._done[self._order[result.cell].popleft()] = result
        now = time.monotonic()
        if now - self._written_at >= self.interval_s or len(self._done) == self._total:
            self._written_at = now
            self.write()

    def write(self, **extra: Any) -> None:
        """The summary so far, with ``extra`` keys (the cluster's report, ...)."""
        summary = summarise([self._done[index] for index in sorted(self._done)])
        summary["pending"] = self._total - len(self._done)
        write_summary(summary | extra, self.path)
