"""``ato campaign --cluster ADDRESS``: a campaign's runs on a Dask distributed cluster.

The client (the ``ato campaign`` process) connects to a running scheduler (``tcp://host:8786``,
or ``tls://`` with the certificates of Dask's configuration), submits one task a cell and takes
each result as it ends, in the order they end; the results come back in the cells' order, as
from the local pool (:func:`deploy.scenario.campaign.run_campaign`). A task is
:func:`deploy.scenario.campaign.run_cell` in a worker process of the cluster, which must run the
same commit of the project (``pip install -e .``); a scenario given as a file travels with its
task as text, so a worker needs only the library's scenarios and lines.

**A worker lost mid-run.** When a worker dies (killed, its machine gone), the scheduler gives
the runs it held to other workers: Dask's own rescheduling, bounded by the scheduler's
``distributed.scheduler.allowed-failures`` (3 by default: a run that took down four workers is
given up, :class:`distributed.KilledWorker`, and is a crash of its cell, as a worker that dies
in the local pool). Each run logs its start to the scheduler's event log under a topic of the
campaign's own; a cell that started more than once was retried, and the summary counts them
(:class:`ClusterReport`). A start logged by a worker killed within milliseconds of it may be
lost, so the count is a lower bound.
"""

from __future__ import annotations

import collections
import os
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import CancelledError
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from deploy._exceptions import DeployError
from deploy.scenario.campaign import Cell, CellResult, run_campaign, run_cell

__all__ = ["ClusterError", "ClusterReport", "retry_report", "run_cells", "run_on_cluster"]

LOCAL = "local"
"""``--cluster local``: a Dask cluster of ``--workers`` processes started for the campaign."""
CONNECT_TIMEOUT_S = 30.0
"""How long the client waits for the scheduler, and then for a first worker."""


class ClusterError(DeployError):
    """The cluster cannot be reached, has no worker, or was lost during the campaign."""


@dataclass(frozen=True)
class ClusterReport:
    """What the cluster did beyond running each cell once (the summary's ``cluster``)."""

    address: str
    workers: int
    """Workers connected when the campaign started."""
    retried: dict[str, int] = field(default_factory=dict)
    """By cell label: the runs started again after their worker was lost."""
    workers_seen: int = 0
    """Distinct workers that started a run."""

    @property
    def retries(self) -> int:
        return sum(self.retried.values())

    def as_json(self) -> dict[str, Any]:
        return {
            "address": self.address,
            "workers": self.workers,
            "workers_seen": self.workers_seen,
            "retries": self.retries,
            "retried": dict(sorted(self.retried.items())),
        }


def cluster_task(index: int, cell: Cell, text: str | None, topic: str) -> CellResult:
    """A cell's run in a worker of the cluster; its start is logged first."""
    from distributed import get_worker

    try:
        worker = get_worker()
    except ValueError:  # not in a worker (a test calling it directly)
        pass
    else:
        worker.log_event(topic, {"index": index, "worker": worker.address, "pid": os.getpid()})
    return run_cell(cell, text)


def _scenario_text(cell: Cell) -> str | None:
    """The scenario file's text when the cell names a file (else a library name: None)."""
    path = Path(cell.scenario)
    return path.read_text(encoding="utf-8") if path.is_file() else None


def run_on_cluster(
    cells: Sequence[Cell],
    *,
    address: str,
    on_result: Callable[[CellResult], None] | None = None,
    timeout_s: float = CONNECT_TIMEOUT_S,
) -> tuple[list[CellResult], ClusterReport]:
    """Every cell on the cluster of the scheduler at ``address``; the results in the cells'
    order, ``on_result`` called for each as it ends, and what the cluster retried.

    Raises
    ------
    ClusterError
        No scheduler at ``address`` (within ``timeout_s``), no worker joined it, or the
        scheduler was lost before every run ended (the results given to ``on_result`` so far
        are kept by the caller).
    """
    from distributed import Client, KilledWorker, as_completed

    _check_tls(address)
    try:
        client = Client(address, timeout=timeout_s, set_as_default=False)  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError, ValueError) as exc:
        raise ClusterError(f"no Dask scheduler at {address}: {exc}") from exc
    topic = f"ato-campaign-{uuid.uuid4().hex}"
    try:
        try:
            client.wait_for_workers(1, timeout=timeout_s)
        except TimeoutError as exc:
            raise ClusterError(f"the scheduler at {address} has no worker") from exc
        workers = len(client.scheduler_info(n_workers=-1)["workers"])
        futures = {
            client.submit(
                cluster_task, index, cell, _scenario_text(cell), topic, key=f"{topic}-{index}"
            ): index
            for index, cell in enumerate(cells)
        }
        results: dict[int, CellResult] = {}
        try:
            for future in as_completed(futures, loop=client.loop):  # type: ignore[no-untyped-call]
                index = futures[future]
                try:
                    result = future.result()
                except KilledWorker as exc:
                    result = CellResult(cells[index], None, f"the run killed its workers: {exc}")
                future.release()
                results[index] = result
                if on_result is not None:
                    on_result(result)
        except (CancelledError, OSError) as exc:
            raise ClusterError(f"the scheduler at {address} was lost: {exc!r}") from exc
        report = retry_report(client.get_events(topic), cells, address=address, workers=workers)
    finally:
        client.close()  # type: ignore[no-untyped-call]
    return [results[index] for index in range(len(cells))], report


def _check_tls(address: str) -> None:
    """A ``tls://`` address needs the client's certificate in Dask's configuration."""
    from distributed.security import Security

    if address.startswith("tls://"):
        context = Security().get_connection_args("client").get("ssl_context")  # type: ignore[no-untyped-call]
        if context is None:
            raise ClusterError(
                f"{address} is TLS: set DASK_DISTRIBUTED__COMM__TLS__CA_FILE, "
                "...__TLS__CLIENT__CERT and ...__TLS__CLIENT__KEY (docs/scenarios.md)"
            )


def retry_report(
    events: Sequence[tuple[float, Any]], cells: Sequence[Cell], *, address: str, workers: int
) -> ClusterReport:
    """The starts the runs logged, counted: a cell started ``n`` times was retried ``n - 1``."""
    starts: collections.Counter[int] = collections.Counter()
    seen: set[str] = set()
    for _time, message in events:
        if isinstance(message, dict) and isinstance(message.get("index"), int):
            starts[message["index"]] += 1
            seen.add(str(message.get("worker")))
    retried = {cells[index].label: n - 1 for index, n in starts.items() if n > 1}
    return ClusterReport(address, workers, retried, len(seen))


def run_cells(
    cells: Sequence[Cell],
    *,
    workers: int,
    cluster: str | None = None,
    on_result: Callable[[CellResult], None] | None = None,
) -> tuple[list[CellResult], ClusterReport | None]:
    """On the cluster at ``cluster`` if one is given, else over ``workers`` local processes.

    ``cluster="local"`` starts a Dask ``LocalCluster`` of ``workers`` one-thread processes in
    this process for the campaign (the same path as a remote cluster, on one machine)."""
    if cluster is None:
        return run_campaign(cells, workers=workers, on_result=on_result), None
    if cluster == LOCAL:
        from distributed import LocalCluster

        with LocalCluster(  # type: ignore[no-untyped-call]
            n_workers=max(1, workers),
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as local:
            return run_on_cluster(cells, address=local.scheduler_address, on_result=on_result)
    return run_on_cluster(cells, address=cluster, on_result=on_result)
