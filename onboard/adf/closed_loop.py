"""AD in closed loop on the point-mass plant, for tests and benchmarks of the ADF alone.

The controller sees the plant's true distance and speed (ideal sensors, until the localisation
issue), while the plant may carry a model mismatch. Records what the KPIs need: speed error,
overspeed against the MRSP, accelerations, traction energy, arrivals at stops and NMPC times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from onboard.adf.autonomous import AutonomousDriving
from onboard.adf.nmpc import NmpcController, NmpcStats
from onboard.adf.odp import OdpPlan
from onboard.plant.point_mass import PointMassModel, PointMassParameters

__all__ = ["ClosedLoopRecord", "Stop", "run_autonomous_journey"]

FloatArray = npt.NDArray[np.float64]
STOPPED_MPS = 0.01
STOP_SEARCH_M = 5.0


@dataclass(frozen=True)
class Stop:
    """A stop of the journey: distance from the start [m], planned arrival [s]."""

    distance_m: float
    planned_arrival_s: float


@dataclass(frozen=True)
class ClosedLoopRecord:
    times_s: FloatArray
    speeds_mps: FloatArray
    reference_speeds_mps: FloatArray
    accelerations_mps2: FloatArray
    max_overspeed_mps: float
    arrivals: dict[int, tuple[float, float]]
    """Stop index → (arrival time [s], stop error [m])."""
    traction_energy_j: float
    nmpc: NmpcStats


def run_autonomous_journey(
    plan: OdpPlan,
    *,
    stops: list[Stop],
    model: PointMassParameters,
    truth: PointMassParameters,
    controller: NmpcController,
    duration_s: float,
    plant_step_s: float = 0.01,
) -> ClosedLoopRecord:
    """Drive the plan with the NMPC (model ``model``) on a plant with parameters ``truth``."""
    track_map = plan.track_map
    driving = AutonomousDriving(plan, model, controller)
    plant = PointMassModel(truth)
    control_s = controller.config.step_s
    substeps = round(control_s / plant_step_s)
    times, speeds, references, accelerations = [], [], [], []
    overspeed = -np.inf
    arrivals: dict[int, tuple[float, float]] = {}
    for k in range(round(duration_s / control_s)):
        now = k * control_s
        force = driving.force_n(
            now, distance_m=plant.position_m, speed_mps=plant.speed_mps,
            applied_force_n=plant.applied_force_n,
        )  # fmt: skip
        for _ in range(substeps):
            chainage = plan.chainage_m(plant.position_m)
            plant.step(
                plant_step_s, force, gradient_permille=track_map.gradient_permille(chainage),
                curve_radius_m=track_map.curve_radius_m(chainage),
            )  # fmt: skip
            overspeed = max(overspeed, plant.speed_mps - track_map.mrsp_mps(chainage))
        times.append(now + control_s)
        speeds.append(plant.speed_mps)
        references.append(plan.reference(now + control_s)[1])
        accelerations.append(plant.acceleration_mps2)
        _note_arrival(arrivals, stops, now + control_s, plant)
    return ClosedLoopRecord(
        times_s=np.array(times), speeds_mps=np.array(speeds),
        reference_speeds_mps=np.array(references), accelerations_mps2=np.array(accelerations),
        max_overspeed_mps=float(overspeed), arrivals=arrivals,
        traction_energy_j=plant.traction_energy_j, nmpc=controller.stats,
    )  # fmt: skip


def _note_arrival(
    arrivals: dict[int, tuple[float, float]], stops: list[Stop], at_s: float, plant: PointMassModel
) -> None:
    if plant.speed_mps >= STOPPED_MPS:
        return
    for index, stop in enumerate(stops):
        near = abs(plant.position_m - stop.distance_m) < STOP_SEARCH_M
        if index not in arrivals and near:
            arrivals[index] = (at_s, plant.position_m - stop.distance_m)
