"""Replanning: a shortened movement authority while driving autonomously."""

from __future__ import annotations

from onboard.adf.autonomous import AutonomousDriving
from onboard.adf.nmpc import NmpcController
from onboard.adf.odp import plan_legs, replan_to_stop
from onboard.plant import URV_PARAMETERS, PointMassModel
from onboard.plant.point_mass import with_model_mismatch
from trackdb import TrackMap, load_seed_line

CONTROL_S, PLANT_S = 0.2, 0.01
START_M = 200.0
EOA_MARGIN_M = 5.0


def test_a_shortened_movement_authority_stops_the_train_before_the_new_end() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    plan = plan_legs(
        ring, start_chainage_m=START_M, stops=[(3200.0, 500.0, 500.0)], cap_mps=40 / 3.6
    )
    controller = NmpcController(URV_PARAMETERS)
    driving = AutonomousDriving(plan, URV_PARAMETERS, controller)
    plant = PointMassModel(with_model_mismatch(URV_PARAMETERS))
    end_of_authority_m: float | None = None
    for k in range(round(260.0 / CONTROL_S)):
        now = k * CONTROL_S
        if k == round(120.0 / CONTROL_S):
            # The trackside shortens the MA: its end is now 300 m ahead of the train.
            end_of_authority_m = plant.position_m + 300.0
            driving = AutonomousDriving(
                replan_to_stop(
                    ring, now_s=now, start_chainage_m=START_M, distance_m=plant.position_m,
                    speed_mps=plant.speed_mps,
                    stop_distance_m=end_of_authority_m - EOA_MARGIN_M - plant.position_m,
                    cruise_mps=plant.speed_mps,
                ),
                URV_PARAMETERS, controller,
            )  # fmt: skip
            controller.reset()
        force = driving.force_n(
            now, distance_m=plant.position_m, speed_mps=plant.speed_mps,
            applied_force_n=plant.applied_force_n,
        )  # fmt: skip
        for _ in range(round(CONTROL_S / PLANT_S)):
            chainage = ring.normalise(START_M + plant.position_m)
            plant.step(PLANT_S, force, gradient_permille=ring.gradient_permille(chainage))
    assert end_of_authority_m is not None
    assert plant.speed_mps == 0.0
    assert plant.position_m <= end_of_authority_m
    assert plant.position_m >= end_of_authority_m - EOA_MARGIN_M - 1.0
