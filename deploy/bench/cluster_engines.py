"""Dask distributed against Ray on one machine, for ``ato campaign --cluster`` (issue 23).

One repetition a process (``python -m deploy.bench.cluster_engines dask|ray``; Ray is not a
dependency of the project: run it from a throwaway environment that has Ray and sees the
project, docs/decisions.md says how). It prints one JSON line:

- ``startup_s``: a local cluster of 2 one-thread worker processes up and a first trivial task's
  result back (Dask: ``LocalCluster`` and ``Client``; Ray: ``ray.init``).
- ``trivial_ms``: 200 trivial tasks submitted at once, all results back, per task.
- ``run_cold_s`` / ``run_warm_s``: one campaign cell (``vc-A`` seed 0) on a worker that has not
  yet imported the stack, then on one that has; ``inline_s``: the same cell in this process,
  warm.
"""

from __future__ import annotations

import importlib
import json
import sys
import time
from collections.abc import Callable
from typing import Any

__all__ = ["bench_dask", "bench_ray", "main"]

TRIVIAL_TASKS = 200
CELL = ("vc-A", 0)
"""The campaign cell run as the real task: by name, so that this module imports nothing of the
stack (a worker process imports the stack when its first real task comes, for both engines)."""


def _trivial(value: int) -> int:
    return value + 1


def _run_cell(name: str, seed: int) -> bool:
    from deploy.scenario.campaign import Cell, run_cell

    return run_cell(Cell(name, seed)).kpis is not None


def _timed(work: Callable[[], Any]) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start


def bench_dask() -> dict[str, float]:
    distributed = importlib.import_module("distributed")
    start = time.perf_counter()
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    client = distributed.Client(cluster)
    client.submit(_trivial, 0, pure=False).result()
    figures = {"startup_s": time.perf_counter() - start}
    try:
        trivial = _timed(
            lambda: client.gather(
                [client.submit(_trivial, i, pure=False) for i in range(TRIVIAL_TASKS)]
            )
        )
        figures["trivial_ms"] = 1000.0 * trivial / TRIVIAL_TASKS
        worker = next(iter(client.scheduler_info()["workers"]))
        for name in ("run_cold_s", "run_warm_s"):
            figures[name] = _timed(
                lambda: client.submit(_run_cell, *CELL, pure=False, workers=[worker]).result()
            )
    finally:
        client.close()
        cluster.close()
    return figures


def bench_ray() -> dict[str, float]:
    ray = importlib.import_module("ray")
    start = time.perf_counter()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    trivial_task = ray.remote(num_cpus=1)(_trivial)
    ray.get(trivial_task.remote(0))
    figures = {"startup_s": time.perf_counter() - start}
    try:
        trivial = _timed(lambda: ray.get([trivial_task.remote(i) for i in range(TRIVIAL_TASKS)]))
        figures["trivial_ms"] = 1000.0 * trivial / TRIVIAL_TASKS
        # An actor pins both runs to one worker process: cold, then warm.
        actor = ray.remote(num_cpus=1)(_CellActor).remote()
        for name in ("run_cold_s", "run_warm_s"):
            figures[name] = _timed(lambda: ray.get(actor.run.remote(*CELL)))
    finally:
        ray.shutdown()
    return figures


class _CellActor:
    def run(self, name: str, seed: int) -> bool:
        return _run_cell(name, seed)


def main(engine: str) -> None:
    figures = {"dask": bench_dask, "ray": bench_ray}[engine]()
    _run_cell(*CELL)  # the imports
    figures["inline_s"] = _timed(lambda: _run_cell(*CELL))
    sys.stdout.write(json.dumps({"engine": engine} | figures) + "\n")


if __name__ == "__main__":
    main(sys.argv[1])
