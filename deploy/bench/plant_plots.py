"""Figures of seed 003 §7 results (1)–(4), written as PNG files by ``ato bench plant --plots``.

(1) and (2) come from :func:`deploy.bench.vcu_mission.run_energy_mission` on the point mass;
(3) and (4) from :func:`deploy.bench.vcu_manoeuvres.run_manoeuvre` on the bogie model with the VCU
in the loop. Matplotlib draws on its non-interactive Agg canvas, chosen here explicitly (no
pyplot, no global backend), and is imported only when figures are asked for.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from deploy.bench.vcu_manoeuvres import (
    ManoeuvreRecord,
    acceleration_manoeuvre,
    braking_manoeuvre,
    friction_drop_manoeuvre,
    run_manoeuvre,
)
from deploy.bench.vcu_mission import MissionRecord, run_energy_mission
from protocol.units import MPS_PER_KMH

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["PLOT_FILES", "write_plots"]

PLOT_FILES = (
    "seed003_1_full_soc.png",
    "seed003_2_half_soc.png",
    "seed003_3_acceleration.png",
    "seed003_3_braking.png",
    "seed003_4_friction_drop.png",
)
"""File names, in the order of seed 003 §7's results."""

KW_PER_W = 1e-3
PHASE_COLOURS = {"electric": "tab:green", "blended": "tab:olive", "pneumatic": "tab:grey"}


def _figure(rows: int, title: str) -> tuple[Figure, list[Axes]]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9.0, 3.2 * rows), layout="constrained")
    FigureCanvasAgg(figure)
    axes = [figure.add_subplot(rows, 1, row + 1) for row in range(rows)]
    figure.suptitle(title)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    return figure, axes


def _mission_figure(record: MissionRecord, title: str) -> Figure:
    figure, (speed_ax, power_ax) = _figure(2, title)
    minutes = record.time_s / 60.0
    speed_ax.plot(minutes, record.speed_mps / MPS_PER_KMH, color="tab:blue", label="speed")
    speed_ax.set_ylabel("speed [km/h]")
    speed_ax.set_ylim(0.0, 220.0)
    soc_ax = speed_ax.twinx()
    soc_ax.plot(minutes, record.soc * 100.0, color="tab:red", label="SOC")
    soc_ax.set_ylabel("SOC [%]")
    soc_ax.set_ylim(0.0, 100.0)
    speed_ax.legend(loc="lower left")
    soc_ax.legend(loc="lower right")
    for series, label in (
        (record.drives_power_w, "drives"),
        (record.battery_power_w, "batteries"),
        (record.range_extender_power_w, "range extender"),
    ):
        power_ax.plot(minutes, series * KW_PER_W, label=label)
    power_ax.set_ylabel("power [kW]")
    power_ax.set_xlabel("time [min]")
    power_ax.legend(loc="center right")
    return figure


def _torque_axes(ax: Axes, record: ManoeuvreRecord, title: str) -> None:
    ax.plot(record.time_s, record.motor_torque_front_nm, label="front axle")
    ax.plot(record.time_s, record.motor_torque_rear_nm, "--", label="rear axle")
    ax.set_ylabel("motor torque [N·m]")
    ax.set_title(title, fontsize="medium")
    ax.legend(loc="lower right")


def _acceleration_figure(forwards: ManoeuvreRecord, reverse: ManoeuvreRecord) -> Figure:
    figure, (speed_ax, forward_ax, reverse_ax) = _figure(
        3, "Seed 003 §7.3: acceleration, front/rear torque split"
    )
    speed_ax.plot(forwards.time_s, forwards.speed_mps / MPS_PER_KMH, label="speed")
    speed_ax.set_ylabel("speed [km/h]")
    force_ax = speed_ax.twinx()
    force_ax.plot(forwards.time_s, forwards.force_demand_n * KW_PER_W, color="tab:red")
    force_ax.set_ylabel("force demand [kN]", color="tab:red")
    _torque_axes(forward_ax, forwards, "forwards: the rear axle trails and starts alone")
    _torque_axes(reverse_ax, reverse, "reverse: the front axle trails and starts alone")
    return figure


def _braking_figure(record: ManoeuvreRecord) -> Figure:
    figure, (speed_ax, torque_ax) = _figure(2, "Seed 003 §7.3: braking in three phases")
    speed_ax.plot(record.time_s, record.speed_mps / MPS_PER_KMH, label="speed")
    speed_ax.set_ylabel("speed [km/h]")
    for phase, colour in PHASE_COLOURS.items():
        inside = record.braking_phase == phase
        if inside.any():
            times = record.time_s[inside]
            for ax in (speed_ax, torque_ax):
                ax.axvspan(float(times[0]), float(times[-1]), color=colour, alpha=0.12)
            speed_ax.text(float(np.mean(times)), 62.0, phase, ha="center", fontsize="small")
    speed_ax.set_ylim(0.0, 70.0)
    total = record.electric_braking_torque_nm + record.pneumatic_braking_torque_nm
    torque_ax.plot(record.time_s, record.braking_demand_nm, "k:", label="demand")
    torque_ax.plot(record.time_s, record.electric_braking_torque_nm, label="electric")
    torque_ax.plot(record.time_s, record.pneumatic_braking_torque_nm, label="pneumatic")
    torque_ax.plot(record.time_s, total, "--", label="total")
    torque_ax.set_ylabel("braking torque, both axles [N·m]")
    torque_ax.legend(loc="center left")
    return figure


def _friction_figure(record: ManoeuvreRecord) -> Figure:
    figure, (speed_ax, torque_ax) = _figure(2, "Seed 003 §7.4: sharp friction drop")
    speed_ax.plot(record.time_s, record.speed_mps / MPS_PER_KMH, label="true speed")
    speed_ax.plot(
        record.time_s, record.wheel_speed_front_mps / MPS_PER_KMH, label="front wheel (ω R)"
    )
    speed_ax.plot(
        record.time_s, record.wheel_speed_rear_mps / MPS_PER_KMH, "--", label="rear wheel (ω R)"
    )
    speed_ax.set_ylabel("speed [km/h]")
    speed_ax.legend(loc="upper left")
    _torque_axes(torque_ax, record, "motor torques; slip detections marked")
    slips = record.slip_front | record.slip_rear
    torque_ax.plot(
        record.time_s[slips], np.zeros(int(slips.sum())), "rx", markersize=4, label="slip"
    )
    adhesion_ax = torque_ax.twinx()
    adhesion_ax.plot(record.time_s, record.adhesion_factor, color="tab:red", alpha=0.6)
    adhesion_ax.set_ylabel("adhesion factor (μ₀ scale) [–]", color="tab:red")
    adhesion_ax.set_ylim(0.0, 1.1)
    return figure


def write_plots(plots_dir: Path, *, distance_km: float = 200.0) -> list[Path]:
    """Run seed 003 §7's results and write one PNG per figure into ``plots_dir``.

    ``distance_km`` [km] is the length of the energy missions (1) and (2); the manoeuvres of
    (3) and (4) are fixed. Returns the paths written, in the order of :data:`PLOT_FILES`.
    """
    plots_dir.mkdir(parents=True, exist_ok=True)
    distance_m = distance_km * 1000.0
    figures = [
        _mission_figure(
            run_energy_mission(initial_soc=1.0, distance_m=distance_m),
            "Seed 003 §7.1: 200 km/h from 100 % SOC",
        ),
        _mission_figure(
            run_energy_mission(initial_soc=0.5, distance_m=distance_m),
            "Seed 003 §7.2: 200 km/h from 50 % SOC",
        ),
        _acceleration_figure(
            run_manoeuvre(acceleration_manoeuvre(1)), run_manoeuvre(acceleration_manoeuvre(-1))
        ),
        _braking_figure(run_manoeuvre(braking_manoeuvre())),
        _friction_figure(run_manoeuvre(friction_drop_manoeuvre())),
    ]
    paths = []
    for name, figure in zip(PLOT_FILES, figures, strict=True):
        path = plots_dir / name
        figure.savefig(path, dpi=110)
        paths.append(path)
    return paths
