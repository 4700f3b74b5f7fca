"""The plant benchmark's own code keeps working (its timings are printed, not tested)."""

from __future__ import annotations

import pytest

from deploy.bench_plant import bench_plant, stand_in_driver


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
