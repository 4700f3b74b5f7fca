"""``ato bench trackdb``: the cost of each TrackMap query, per call.

Every query is timed call by call with :func:`time.perf_counter_ns` (the figure includes one
clock read, some 50 ns) over inputs drawn with a fixed seed: chainages uniform over the line,
and GPS fixes made from :meth:`~trackdb.TrackMap.geodetic_at` plus a few metres of noise, with
the last estimate ``near_m`` a few tens of metres off the truth. The garbage collector is paused
while timing, as :mod:`timeit` does. Measured on milano-bologna (200 km, a polyline point every
50 m), where the targets apply, and on bologna-ring (5.7 km, every 10 m).
"""

from __future__ import annotations

import gc
import random
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from rich.console import Console
from rich.table import Table

from deploy.stats import percentiles
from trackdb import TrackMap, load_seed_line
from trackdb.builder import enu_to_geodetic, geodetic_to_enu

__all__ = ["BENCH_LINES", "TARGETS_MEDIAN_US", "bench_trackdb", "time_calls"]

BENCH_LINES = ("milano-bologna", "bologna-ring")
TARGETS_MEDIAN_US = {
    "mrsp_mps": 5.0,
    "gradient_permille": 5.0,
    "speed_limit_mps": 5.0,
    "project (bounded)": 50.0,
}
"""Median cost [µs] each query must stay under on milano-bologna."""
TARGET_LINE = "milano-bologna"
WARMUP_CALLS = 200
GPS_NOISE_M = 3.0
"""Standard deviation [m] of the GPS noise, east and north."""
ESTIMATE_ERROR_M = 30.0
"""Largest error [m] of the chainage estimate passed as ``near_m``."""
LOOKAHEAD_M = 10_000.0
"""Look-ahead [m] of the window queries, about what a planner at 300 km/h asks for."""
PLANNER_SAMPLES = 200


@dataclass(frozen=True)
class _Case:
    query: str
    function: Callable[[Any], object]
    arguments: Sequence[Any]


def time_calls(function: Callable[[Any], object], arguments: Sequence[Any]) -> list[int]:
    """Time ``function(argument)`` for each argument, one call at a time.

    Parameters
    ----------
    function : callable
        The query, taking one argument.
    arguments : sequence
        One argument per call; the first ``WARMUP_CALLS`` are also run once, untimed, first.

    Returns
    -------
    list of int
        The duration [ns] of each call, in the order of ``arguments``.
    """
    for argument in arguments[:WARMUP_CALLS]:
        function(argument)
    clock = time.perf_counter_ns
    samples_ns = [0] * len(arguments)
    collecting = gc.isenabled()
    gc.disable()
    try:
        for index, argument in enumerate(arguments):
            started_ns = clock()
            function(argument)
            samples_ns[index] = clock() - started_ns
    finally:
        if collecting:
            gc.enable()
    return samples_ns


def _gps_fixes(
    track: TrackMap, chainages_m: list[float], rng: random.Random
) -> list[tuple[float, float, float]]:
    """(latitude [deg], longitude [deg], near_m [m]) for fixes near each chainage."""
    first = track.line.geodetic[0]
    origin = (first.latitude_deg, first.longitude_deg)
    fixes = []
    for chainage_m in chainages_m:
        latitude_deg, longitude_deg, _ = track.geodetic_at(chainage_m)
        east_m, north_m = geodetic_to_enu(latitude_deg, longitude_deg, *origin)
        noisy = enu_to_geodetic(
            east_m + rng.gauss(0.0, GPS_NOISE_M), north_m + rng.gauss(0.0, GPS_NOISE_M), *origin
        )
        near_m = chainage_m + rng.uniform(-ESTIMATE_ERROR_M, ESTIMATE_ERROR_M)
        fixes.append((*noisy, near_m))
    return fixes


def _cases(track: TrackMap, count: int, rng: random.Random) -> list[_Case]:
    chainages_m = [rng.uniform(0.0, track.length_m) for _ in range(count)]
    fixes = _gps_fixes(track, chainages_m, rng)
    planner_distances_m = [LOOKAHEAD_M * i / PLANNER_SAMPLES for i in range(PLANNER_SAMPLES)]
    return [
        _Case("mrsp_mps", track.mrsp_mps, chainages_m),
        _Case("gradient_permille", track.gradient_permille, chainages_m),
        _Case("speed_limit_mps", track.speed_limit_mps, chainages_m),
        _Case("curvature_per_m", track.curvature_per_m, chainages_m),
        _Case("next_stopping_point", track.next_stopping_point, chainages_m),
        _Case(
            "balise_groups_ahead 10 km",
            lambda chainage_m: track.balise_groups_ahead(chainage_m, LOOKAHEAD_M),
            chainages_m,
        ),
        _Case(
            "mrsp_window 10 km",
            lambda chainage_m: track.mrsp_window(chainage_m, LOOKAHEAD_M),
            chainages_m,
        ),
        _Case(
            f"mrsp_ahead_mps ×{PLANNER_SAMPLES}",
            lambda chainage_m: track.mrsp_ahead_mps(chainage_m, planner_distances_m),
            chainages_m,
        ),
        _Case("geodetic_at", track.geodetic_at, chainages_m),
        _Case("project (bounded)", lambda fix: track.project(fix[0], fix[1], near_m=fix[2]), fixes),
        _Case("project (global)", lambda fix: track.project(fix[0], fix[1]), fixes),
    ]


def _figures(samples_ns: list[int]) -> dict[str, float]:
    median_ns, p99_ns, max_ns = percentiles(samples_ns, (50, 99, 100))
    return {
        "count": float(len(samples_ns)),
        "median_us": median_ns / 1e3,
        "p99_us": p99_ns / 1e3,
        "max_us": max_ns / 1e3,
    }


def _table(results: dict[str, dict[str, dict[str, float]]]) -> Table:
    table = Table(title="TrackMap queries, per call")
    for column in ("line", "query", "n", "median µs", "p99 µs", "max µs", "target µs"):
        table.add_column(column, justify="left" if column in ("line", "query") else "right")
    for line_id, queries in results.items():
        table.add_section()
        for row, (query, figures) in enumerate(queries.items()):
            target = figures.get("target_median_us")
            verdict = "" if target is None else ("✓" if figures["median_us"] <= target else "✗")
            table.add_row(
                "" if row else line_id,
                query,
                f"{figures['count']:.0f}",
                f"{figures['median_us']:.2f}",
                f"{figures['p99_us']:.2f}",
                f"{figures['max_us']:.1f}",
                "" if target is None else f"{verdict} ≤ {target:g}",
            )
    return table


def bench_trackdb(
    count: int = 20000, *, seed: int = 20240603
) -> dict[str, dict[str, dict[str, float]]]:
    """Time every TrackMap query on the bench lines, print a table, return the figures.

    Parameters
    ----------
    count : int
        Calls timed per query and line.
    seed : int
        Seed of the random chainages and GPS noise.

    Returns
    -------
    dict
        By line, then by query: ``count``, ``median_us``, ``p99_us``, ``max_us`` [µs], and
        ``target_median_us`` [µs] where a target applies.
    """
    rng = random.Random(seed)
    results: dict[str, dict[str, dict[str, float]]] = {}
    for line_id in BENCH_LINES:
        track = TrackMap(load_seed_line(line_id))
        results[line_id] = {}
        for case in _cases(track, count, rng):
            figures = _figures(time_calls(case.function, case.arguments))
            target = TARGETS_MEDIAN_US.get(case.query) if line_id == TARGET_LINE else None
            if target is not None:
                figures["target_median_us"] = target
            results[line_id][case.query] = figures
    console = Console(width=100)
    console.print(_table(results))
    console.print(
        f"GPS fixes: σ = {GPS_NOISE_M:g} m of noise, estimate within ±{ESTIMATE_ERROR_M:g} m;"
        f" targets (median) apply on {TARGET_LINE}."
    )
    return results
