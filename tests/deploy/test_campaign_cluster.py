"""`ato campaign --cluster`: on a Dask scheduler and two workers started as separate processes,
the same summary as over local worker processes; a worker killed mid-run has its run retried."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from deploy.cli import app
from deploy.ports import free_tcp_port
from deploy.scenario.campaign import Cell, CellResult, PartialSummary
from deploy.scenario.cluster import ClusterReport, retry_report
from tests.deploy.kpi_samples import sample_kpis

MATRIX = ["vc-A", "bologna-ring", "--seeds", "2", "--vary", "duration_s=8"]
"""Four short runs: two VC runs of a fraction of a second, two whole-stack runs of 8 simulated
seconds (some 10 s each here: long enough to be killed in)."""
WALL_CLOCK_KPIS = ("real_time_factor",)


def _start(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    with log.open("wb") as out:
        return subprocess.Popen(
            [sys.executable, "-m", *args], stdout=out, stderr=subprocess.STDOUT, cwd=Path.cwd()
        )


@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A scheduler and two one-thread workers on 127.0.0.1, each its own process; all killed
    at the end, also on a failure."""
    logs = tmp_path_factory.mktemp("cluster")
    address = f"tcp://127.0.0.1:{free_tcp_port()}"
    port = address.rsplit(":", 1)[1]
    no_dashboard = ["--dashboard-address", "127.0.0.1:0"]
    processes = [
        _start(
            ["distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", port]
            + no_dashboard,
            logs / "scheduler.log",
        )
    ]
    try:
        for name in ("a", "b"):
            processes.append(
                _start(
                    ["distributed.cli.dask_worker", address, "--nthreads", "1", "--nworkers", "1"]
                    + ["--host", "127.0.0.1", "--name", name]
                    + no_dashboard,
                    logs / f"worker-{name}.log",
                )
            )
        _wait_for_workers(address, 2)
        yield address
    finally:
        for process in processes:
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def _wait_for_workers(address: str, count: int) -> None:
    from distributed import Client

    with Client(address, timeout=60) as client:
        client.wait_for_workers(count, timeout=120)


def _comparable(summary: dict[str, Any]) -> dict[str, Any]:
    """The summary without what depends on the wall clock or on where the runs were made."""
    summary = dict(summary)
    summary.pop("cluster", None)
    summary["scenarios"] = {
        name: row | {"kpis": {k: v for k, v in row["kpis"].items() if k not in WALL_CLOCK_KPIS}}
        for name, row in summary["scenarios"].items()
    }
    return summary


@pytest.fixture(scope="module")
def local_summary(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    out = tmp_path_factory.mktemp("local") / "summary.json"
    result = CliRunner().invoke(app, ["campaign", *MATRIX, "--workers", "2", "--json", str(out)])
    assert result.exit_code == 0, result.output
    summary: dict[str, Any] = json.loads(out.read_text())
    assert summary["runs"] == 4
    assert summary["pending"] == 0
    return summary


@pytest.mark.scenario
@pytest.mark.e2e
def test_the_cluster_gives_the_summary_of_local_workers(
    cluster: str, local_summary: dict[str, Any], tmp_path: Path
) -> None:
    out = tmp_path / "summary.json"
    result = CliRunner().invoke(
        app, ["campaign", *MATRIX, "--cluster", cluster, "--json", str(out)]
    )
    assert result.exit_code == 0, result.output
    summary = json.loads(out.read_text())
    assert summary["crashed"] == 0
    assert summary["cluster"]["workers"] == 2
    assert summary["cluster"]["retries"] == 0
    assert _comparable(summary) == _comparable(local_summary)


def _logged_starts(client: Any) -> list[dict[str, Any]]:
    """The start events the campaign's runs logged on the scheduler so far."""
    events = client.get_events()
    return [
        message
        for topic, found in events.items()
        if topic.startswith("ato-campaign-")
        for _time, message in found
    ]


@pytest.mark.scenario
@pytest.mark.e2e
def test_a_killed_workers_run_is_retried(
    cluster: str, local_summary: dict[str, Any], tmp_path: Path
) -> None:
    from distributed import Client

    out = tmp_path / "summary.json"
    watcher = Client(cluster, timeout=30)  # one connection, so that the start is seen at once
    before = len(_logged_starts(watcher))
    campaign = subprocess.Popen(
        [sys.executable, "-m", "deploy", "campaign", "bologna-ring", "--seeds", "2"]
        + ["--vary", "duration_s=8", "--cluster", cluster, "--json", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    try:
        deadline = time.monotonic() + 120
        while len(started := _logged_starts(watcher)) == before:
            assert time.monotonic() < deadline, "no run started"
            time.sleep(0.05)
        # At once: an 8 s run takes about a second of wall time on a fast machine (its
        # trackside's start-up the longest part), so a kill a second after its start could
        # come after its end and leave nothing to retry.
        os.kill(started[before]["pid"], signal.SIGKILL)
        output, _ = campaign.communicate(timeout=300)
    finally:
        watcher.close()
        campaign.kill()
        campaign.wait()
    assert campaign.returncode == 0, output.decode(errors="replace")
    summary = json.loads(out.read_text())
    assert summary["runs"] == 2
    assert summary["crashed"] == 0
    assert summary["cluster"]["retries"] >= 1
    killed = f"bologna-ring seed={started[before]['index']} duration_s=8"
    assert summary["cluster"]["retried"][killed] >= 1
    # The retried run gives what the run gives anywhere.
    expected = [c for c in local_summary["cells"] if c["scenario"] == "bologna-ring"]
    assert summary["cells"] == expected


def test_the_partial_summary_is_written_as_the_runs_end(tmp_path: Path) -> None:
    cells = [Cell("s", seed) for seed in range(3)]
    path = tmp_path / "summary.json"
    partial = PartialSummary(cells, path, interval_s=0.0)
    partial.add(CellResult(cells[1], sample_kpis()))
    written = json.loads(path.read_text())
    assert (written["runs"], written["pending"]) == (1, 2)
    assert [c["seed"] for c in written["cells"]] == [1]
    partial.add(CellResult(cells[0], None, "boom"))
    partial.add(CellResult(cells[2], sample_kpis()))
    written = json.loads(path.read_text())
    assert (written["runs"], written["pending"], written["crashed"]) == (3, 0, 1)
    assert [c["seed"] for c in written["cells"]] == [0, 1, 2]


def test_the_retries_are_counted_from_the_runs_starts() -> None:
    cells = [Cell("s", 0), Cell("s", 1)]
    events = [
        (0.0, {"index": 0, "worker": "tcp://a", "pid": 1}),
        (1.0, {"index": 1, "worker": "tcp://b", "pid": 2}),
        (2.0, {"index": 0, "worker": "tcp://b", "pid": 2}),
        (3.0, "not a start"),
    ]
    report = retry_report(events, cells, address="tcp://x:1", workers=2)
    assert report == ClusterReport("tcp://x:1", 2, {"s seed=0": 1}, 2)
    assert report.as_json()["retries"] == 1


def test_a_tls_address_without_certificates_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("CA_FILE", "CLIENT__CERT", "CLIENT__KEY"):
        monkeypatch.delenv(f"DASK_DISTRIBUTED__COMM__TLS__{name}", raising=False)
    result = CliRunner().invoke(
        app, ["campaign", "vc-A", "--seeds", "1", "--cluster", "tls://127.0.0.1:1"]
    )
    assert result.exit_code == 2, result.output
    assert "is TLS" in result.output


def test_a_generated_campaigns_kept_runs_are_in_its_partial_summary(tmp_path: Path) -> None:
    from deploy.scenario.generated import _run_kept
    from deploy.scenario.run_store import RunStore

    cells = []
    for index in range(2):
        scenario = tmp_path / f"gen-{index}.toml"
        scenario.write_text(f"# scenario {index}\n")
        cells.append(Cell(str(scenario), index))
    store = RunStore(tmp_path / "results", "code")
    for cell in cells:
        store.save(CellResult(cell, sample_kpis()))
    path = tmp_path / "summary.json"
    results, report = _run_kept(
        cells,
        store,
        workers=1,
        resume=True,
        on_result=None,
        partial=PartialSummary(cells, path, interval_s=0.0),
    )
    assert report is None
    assert [r.cell for r in results] == cells
    written = json.loads(path.read_text())
    assert (written["runs"], written["pending"]) == (2, 0)
