"""``ato bench up``: a whole ``ato up`` fleet brought up, a vehicle driven over REST through a
journey, its processes measured from /proc, and a clean shutdown."""

from __future__ import annotations

import os
import time

import pytest
from typer.testing import CliRunner

from deploy.bench.up_bench import Journey, UpBenchResult, Usage, _proc_usage
from deploy.cli import app


def test_a_process_s_cpu_and_memory_come_from_proc() -> None:
    usage = _proc_usage(os.getpid())
    assert usage is not None
    cpu_s, rss_mb = usage
    assert cpu_s > 0.0
    assert 10.0 < rss_mb < 10_000.0
    # Work shows as CPU time.
    deadline = time.process_time() + 0.2
    while time.process_time() < deadline:
        pass
    later = _proc_usage(os.getpid())
    assert later is not None
    assert later[0] >= cpu_s + 0.1
    assert _proc_usage(2**22 + 12345) is None  # no such process


def test_cpu_use_is_the_cpu_time_over_the_sampled_span() -> None:
    usage = Usage()
    assert usage.cpu_percent is None
    usage.sample(10.0, 200.0, at_s=100.0)
    assert usage.cpu_percent is None  # one sample: no span
    usage.sample(13.0, 250.0, at_s=120.0)
    usage.sample(15.0, 240.0, at_s=150.0)
    assert usage.cpu_percent == pytest.approx(10.0)  # 5 s of CPU over 50 s
    assert usage.rss_max_mb == 250.0


def test_a_bench_passes_only_when_everything_held() -> None:
    done = Journey("URV1", step=6, ended_s=80.0, stop_error_m=0.05)
    result = UpBenchResult(vehicles=2, driven=1, speed=1.0, journeys=[done])
    result.clean_shutdown = True
    assert result.ok
    result.not_alive["URV2"] += 1
    assert not result.ok
    result.not_alive.clear()
    result.journeys = [Journey("URV1", step=4, failure="engage: 409")]
    assert not result.ok
    result.journeys = [done]
    result.left_behind = [1234]
    assert not result.ok


@pytest.mark.e2e
@pytest.mark.slow
def test_bench_up_drives_a_vehicle_of_a_fleet_and_shuts_it_down() -> None:
    result = CliRunner().invoke(
        app, ["bench", "up", "--vehicles", "1", "--drive", "1", "--speed", "20"]
    )
    assert result.exit_code == 0, result.output
    text = "".join(result.output.split())
    assert "journeysendedattheplatform│1of1" in text
    assert "vehiclesseennotalive(samples)│none" in text
    assert "cleanshutdown│yes" in text
