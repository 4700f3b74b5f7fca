"""The plant benchmark's own code keeps working (its timings are printed, not tested)."""

from __future__ import annotations

from pathlib import Path

import pytest

from deploy.bench.plant_bench import bench_plant, stand_in_driver
from deploy.bench.plant_plots import PLOT_FILES

pytestmark = pytest.mark.scenario


def test_stand_in_driver_drives_then_brakes() -> None:
    start = stand_in_driver(0.0, 0.0, stop_m=1000.0, max_speed_mps=20.0)
    assert start.motor_torque_front_nm == start.motor_torque_rear_nm > 0.0
    assert start.brake_pressure_front_pa == 0.0
    late = stand_in_driver(990.0, 20.0, stop_m=1000.0, max_speed_mps=20.0)
    assert late.motor_torque_front_nm == 0.0
    assert late.brake_pressure_front_pa == late.brake_pressure_rear_pa > 0.0


def test_bench_plant_runs_a_short_mission(capsys: pytest.CaptureFixture[str]) -> None:
    results = bench_plant(distance_km=0.2, max_speed_kmh=60.0, point_mass_steps=300)
    bogie = results["bogie"]
    assert bogie["distance_km"] == pytest.approx(0.2, abs=0.01)
    assert bogie["simulated_s"] > 0.0
    assert bogie["real_time_factor"] > 0.0
    assert 0.0 < results["point_mass"]["median_us"] <= results["point_mass"]["p99_us"]
    assert "Plant models" in capsys.readouterr().out


def test_bench_plant_writes_the_seed003_plots(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plots = tmp_path / "plots"
    bench_plant(distance_km=0.2, max_speed_kmh=60.0, point_mass_steps=100, plots_dir=plots)
    for name in PLOT_FILES:
        data = (plots / name).read_bytes()
        assert data.startswith(b"\x89PNG\r\n\x1a\n"), name
        assert len(data) > 10_000, name
    assert sorted(p.name for p in plots.iterdir()) == sorted(PLOT_FILES)
    assert "wrote" in capsys.readouterr().out
