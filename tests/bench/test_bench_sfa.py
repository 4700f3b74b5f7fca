"""``ato bench sfa`` and ``ato sfa ...``: the benchmark's code runs and prints its figures
beside their targets (timings printed, not tested); the commands' options and exit codes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from deploy.bench.sfa_bench import bench_sfa, imu_cost_us
from deploy.cli import app

pytestmark = pytest.mark.scenario

runner = CliRunner()


@pytest.mark.timeout(300)
def test_bench_sfa_prints_every_figure_beside_its_target(
    capsys: pytest.CaptureFixture[str],
) -> None:
    figures = bench_sfa(
        ring_s=140.0, milano_s=140.0, fuzz_count=3000, imu_count=500, throughput_drive_s=20.0
    )
    out = capsys.readouterr().out
    for text in (
        "position RMS",
        "60 s GPS outage",
        "20 % loss",
        "odometer silent",
        "speed RMS",
        "per IMU packet, median",
        "throughput over UDP",
        "fuzz",
    ):
        assert text in out, text
    rows = figures["accuracy"]
    assert isinstance(rows, list)
    assert len(rows) == 14
    assert all(row.ok is not False for row in rows), [r for r in rows if r.ok is False]
    assert float(figures["udp_datagrams_per_s"]) > 0  # type: ignore[arg-type]


def test_imu_cost_is_measured_per_packet() -> None:
    median_us, p99_us = imu_cost_us(200)
    assert 0 < median_us <= p99_us


def test_record_then_replay_with_chosen_sensors(tmp_path: Path) -> None:
    path = tmp_path / "drive.npz"
    recorded = runner.invoke(app, ["sfa", "record", "--out", str(path), "--duration", "30"])
    assert recorded.exit_code == 0, recorded.output
    replayed = runner.invoke(app, ["sfa", "replay", str(path), "--sensors", "imu,odometer"])
    assert replayed.exit_code == 0, replayed.output
    assert "position error RMS" in replayed.output
    assert "gps" not in replayed.output.split(":")[0]
    wrong = runner.invoke(app, ["sfa", "replay", str(path), "--sensors", "sonar"])
    assert wrong.exit_code != 0
    missing = runner.invoke(app, ["sfa", "replay", str(tmp_path / "none.npz")])
    assert missing.exit_code == 1


def test_listen_rejects_a_bad_address() -> None:
    result = runner.invoke(app, ["sfa", "listen", "--input", "nohost", "--obcu", "h:1"])
    assert result.exit_code != 0


@pytest.mark.timeout(120)
def test_ato_sfa_listen_process_exits_zero_on_stop() -> None:
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    listener = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "deploy",
            "sfa",
            "listen",
            "--input",
            f"127.0.0.1:{port}",
            "--obcu",
            "127.0.0.1:9",
        ],
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        # Wait for the listener's banner, then emulate a short drive at full speed.
        assert listener.stderr is not None
        banner = listener.stderr.readline()
        assert "listening on" in banner
        sent = runner.invoke(
            app, ["sfa", "emulate", "--to", f"127.0.0.1:{port}", "--duration", "5", "--speed", "0"]
        )
        assert sent.exit_code == 0, sent.output
        assert listener.wait(timeout=60) == 0
        summary = listener.stderr.read()
        assert "processed" in summary
        assert "'stop': 1" in summary
    finally:
        if listener.poll() is None:
            listener.kill()
            listener.wait()
        if listener.stderr is not None:
            listener.stderr.close()
