"""``ato bench plant``: how fast the plant models run.

Two figures. The bogie model's real-time factor (simulated over wall time) over the seed-003
mission: 200 km on level track at up to 200 km/h, from standstill to standstill, stepped every
10 ms. It is driven by a stand-in speed loop, for the bench only (the VCU is not in the loop):
a proportional speed controller on a braking curve, equal torque on both axles in traction,
pneumatic brakes alone to slow down. Targets: ≥ 10× real time for the bogie model, and ≤ 5 µs
per 10 ms step of the point-mass model (median and p99 of single timed calls, as
:func:`deploy.bench.trackdb_bench.time_calls` times them).
"""

from __future__ import annotations

import math
import random
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

from deploy.bench.trackdb_bench import time_calls
from deploy.stats import percentiles
from onboard.plant.bogie import DEFAULT_SUBSTEP_S, BogieModel
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS, BogieParameters
from onboard.plant.interfaces import ActuatorCommands
from onboard.plant.point_mass import URV_PARAMETERS, PointMassModel
from protocol.units import J_PER_KWH, MPS_PER_KMH

__all__ = [
    "MISSION_DISTANCE_KM",
    "MISSION_SPEED_KMH",
    "PLANT_STEP_S",
    "TARGET_POINT_MASS_STEP_US",
    "TARGET_REAL_TIME_FACTOR",
    "bench_plant",
    "stand_in_driver",
]

MISSION_DISTANCE_KM = 200.0
MISSION_SPEED_KMH = 200.0
PLANT_STEP_S = 0.01
TARGET_REAL_TIME_FACTOR = 10.0
TARGET_POINT_MASS_STEP_US = 5.0
DRIVER_DECELERATION_MPS2 = 0.5
"""Deceleration [m/s²] of the stand-in driver's braking curve."""
DRIVER_GAIN_PER_S = 1.0
"""Speed-loop gain [1/s]: the acceleration asked per m/s of speed error."""


def stand_in_driver(
    position_m: float,
    speed_mps: float,
    stop_m: float,
    max_speed_mps: float,
    parameters: BogieParameters = URV_BOGIE_PARAMETERS,
) -> ActuatorCommands:
    """Bench-only speed loop: actuator references to run at ``max_speed_mps`` and stop at
    ``stop_m``; not the VCU."""
    curve_mps = math.sqrt(2.0 * DRIVER_DECELERATION_MPS2 * max(stop_m - position_m, 0.0))
    target_mps = min(max_speed_mps, curve_mps)
    davis = (
        URV_PARAMETERS.davis_a_n
        + URV_PARAMETERS.davis_b_n_per_mps * speed_mps
        + URV_PARAMETERS.davis_c_n_per_mps2 * speed_mps**2
    )
    mass = URV_PARAMETERS.mass_kg * (1.0 + URV_PARAMETERS.rotating_mass_factor)
    force_n = mass * DRIVER_GAIN_PER_S * (target_mps - speed_mps) + davis
    axle_torque_nm = 0.5 * force_n * parameters.wheel_radius_m
    if axle_torque_nm >= 0.0:
        return ActuatorCommands(
            motor_torque_front_nm=axle_torque_nm, motor_torque_rear_nm=axle_torque_nm
        )
    pressure_pa = -axle_torque_nm / parameters.brake_gain_m3
    return ActuatorCommands(brake_pressure_front_pa=pressure_pa, brake_pressure_rear_pa=pressure_pa)


def _run_mission(distance_km: float, max_speed_kmh: float) -> dict[str, float]:
    stop_m = distance_km * 1000.0
    max_speed_mps = max_speed_kmh * MPS_PER_KMH
    model = BogieModel()
    # Generous: the cruise, the acceleration and the braking, and a minute to settle.
    limit_s = stop_m / max_speed_mps + 2.0 * max_speed_mps / DRIVER_DECELERATION_MPS2 + 60.0
    clock = time.perf_counter
    started = clock()
    truth = model.truth()
    top_mps = 0.0
    while truth.time_s < limit_s:
        commands = stand_in_driver(truth.position_m, truth.speed_mps, stop_m, max_speed_mps)
        model.step(PLANT_STEP_S, commands)
        truth = model.truth()
        top_mps = max(top_mps, truth.speed_mps)
        if truth.position_m > stop_m - 1.0 and abs(truth.speed_mps) < 0.01:
            break
    wall_s = clock() - started
    return {
        "simulated_s": truth.time_s,
        "wall_s": wall_s,
        "real_time_factor": truth.time_s / wall_s,
        "distance_km": truth.position_m / 1000.0,
        "top_speed_kmh": top_mps / MPS_PER_KMH,
        "traction_energy_kwh": truth.traction_energy_j / J_PER_KWH,
    }


def _time_point_mass(steps: int, seed: int) -> dict[str, float]:
    rng = random.Random(seed)
    model = PointMassModel(speed_mps=30.0)
    demands_n = [rng.uniform(-5_000.0, 20_000.0) for _ in range(steps)]

    def step(force_n: float) -> None:
        model.step(PLANT_STEP_S, force_n, gradient_permille=2.0)

    samples_ns = time_calls(step, demands_n)
    median_ns, p99_ns = percentiles(samples_ns, (50, 99))
    return {"count": float(len(samples_ns)), "median_us": median_ns / 1e3, "p99_us": p99_ns / 1e3}


def _verdict(ok: bool) -> str:
    return "✓" if ok else "✗"


def _plant_table(bogie: dict[str, float], point_mass: dict[str, float]) -> Table:
    """Both models' figures beside their targets."""
    table = Table(title="Plant models")
    for column in ("model", "measure", "value", "target"):
        table.add_column(column, justify="left" if column in ("model", "measure") else "right")
    factor_ok = bogie["real_time_factor"] >= TARGET_REAL_TIME_FACTOR
    table.add_row(
        "bogie (10 DOF)",
        f"real-time factor, {bogie['distance_km']:.1f} km in "
        f"{bogie['simulated_s']:.0f} s simulated",
        f"{bogie['real_time_factor']:.1f}×",
        f"{_verdict(factor_ok)} ≥ {TARGET_REAL_TIME_FACTOR:g}×",
    )
    table.add_row("", "wall time", f"{bogie['wall_s']:.1f} s", "")
    table.add_row("", "top speed", f"{bogie['top_speed_kmh']:.1f} km/h", "")
    table.add_row(
        "", "traction energy at the wheels", f"{bogie['traction_energy_kwh']:.1f} kWh", ""
    )
    for figure in ("median_us", "p99_us"):
        ok = point_mass[figure] <= TARGET_POINT_MASS_STEP_US
        table.add_row(
            "point mass" if figure == "median_us" else "",
            f"step cost, {figure.removesuffix('_us')}",
            f"{point_mass[figure]:.2f} µs",
            f"{_verdict(ok)} ≤ {TARGET_POINT_MASS_STEP_US:g} µs",
        )
    return table


def bench_plant(
    *,
    distance_km: float = MISSION_DISTANCE_KM,
    max_speed_kmh: float = MISSION_SPEED_KMH,
    point_mass_steps: int = 100_000,
    seed: int = 20240603,
    plots_dir: Path | None = None,
) -> dict[str, dict[str, float]]:
    """Run both measurements, print a table, return the figures.

    Parameters
    ----------
    distance_km : float
        Mission length [km]; 200 for the seed's mission, a few km for a quick look.
    max_speed_kmh : float
        Top speed of the stand-in driver [km/h].
    point_mass_steps : int
        Point-mass steps timed one by one.
    seed : int
        Seed of the point-mass model's random force demands.
    plots_dir : Path or None
        When given, also run seed 003 §7's results (1)–(4) (energy missions of
        ``distance_km`` on the point mass, manoeuvres on the bogie model with the VCU) and
        write their PNG figures there (:mod:`deploy.bench.plant_plots`).

    Returns
    -------
    dict
        ``bogie``: ``simulated_s``, ``wall_s``, ``real_time_factor``, ``distance_km``,
        ``top_speed_kmh``, ``traction_energy_kwh``; ``point_mass``: ``count``, ``median_us``,
        ``p99_us``.
    """
    results = {
        "bogie": _run_mission(distance_km, max_speed_kmh),
        "point_mass": _time_point_mass(point_mass_steps, seed),
    }
    console = Console(width=100)
    console.print(_plant_table(results["bogie"], results["point_mass"]))
    console.print(
        f"Bogie model stepped every {PLANT_STEP_S * 1000:g} ms (substeps ≤"
        f" {DEFAULT_SUBSTEP_S * 1000:g} ms), driven by a stand-in speed loop, not the VCU."
    )
    if plots_dir is not None:
        from deploy.bench.plant_plots import write_plots

        for path in write_plots(plots_dir, distance_km=distance_km):
            console.print(f"wrote {path}")
    return results
