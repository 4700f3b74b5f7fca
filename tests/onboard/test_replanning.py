"""Replanning while driving autonomously: a shortened movement authority, a new temporary
speed restriction, an obstacle reported ahead, the release of an ETCS intervention."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from onboard.adf.autonomous import AutonomousDriving
from onboard.adf.nmpc import NmpcController
from onboard.adf.odp import OdpPlan, plan_legs
from onboard.adf.odp_energy import plan_energy_legs, replan_from_state
from onboard.plant import URV_PARAMETERS, PointMassModel
from onboard.plant.point_mass import with_model_mismatch
from trackdb import TemporarySpeedRestriction, TrackMap, load_seed_line

pytestmark = pytest.mark.scenario

CONTROL_S, PLANT_S = 0.2, 0.01
START_M = 200.0
EOA_MARGIN_M = 5.0
CAP_MPS = 40 / 3.6


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
                replan_from_state(
                    ring,
                    URV_PARAMETERS,
                    now_s=now,
                    start_chainage_m=START_M,
                    distance_m=plant.position_m,
                    speed_mps=plant.speed_mps,
                    stop_distance_m=end_of_authority_m - EOA_MARGIN_M - plant.position_m,
                    cruise_mps=plant.speed_mps,
                ),
                URV_PARAMETERS,
                controller,
            )
            controller.reset()
        force = driving.force_n(
            now,
            distance_m=plant.position_m,
            speed_mps=plant.speed_mps,
            applied_force_n=plant.applied_force_n,
        )
        for _ in range(round(CONTROL_S / PLANT_S)):
            chainage = ring.normalise(START_M + plant.position_m)
            plant.step(PLANT_S, force, gradient_permille=ring.gradient_permille(chainage))
    assert end_of_authority_m is not None
    assert plant.speed_mps == 0.0
    assert plant.position_m <= end_of_authority_m
    assert plant.position_m >= end_of_authority_m - EOA_MARGIN_M - 1.0


def _drive(
    ring: TrackMap,
    plan: OdpPlan,
    *,
    until_s: float,
    event_s: float,
    on_event: Callable[[float, PointMassModel], OdpPlan | None],
    braking_s: float = 0.0,
) -> tuple[PointMassModel, list[tuple[float, float, float]]]:
    """AD on a mismatched plant; at ``event_s`` the event happens. With ``braking_s`` the ETCS
    intervenes there first: full service braking for that long, AD overridden, and the new
    plan comes from ``on_event`` at its release. Returns the plant and (time, distance, speed)
    samples."""
    controller = NmpcController(URV_PARAMETERS)
    driving = AutonomousDriving(plan, URV_PARAMETERS, controller)
    plant = PointMassModel(with_model_mismatch(URV_PARAMETERS))
    release_s = event_s + braking_s
    trace = []
    for k in range(round(until_s / CONTROL_S)):
        now = k * CONTROL_S
        if abs(now - release_s) < CONTROL_S / 2:
            replanned = on_event(now, plant)
            if replanned is not None:
                driving = AutonomousDriving(replanned, URV_PARAMETERS, controller)
                controller.reset()
        if event_s <= now < release_s:
            force = -URV_PARAMETERS.max_brake_force_n  # the ETCS service brake
        else:
            force = driving.force_n(
                now,
                distance_m=plant.position_m,
                speed_mps=plant.speed_mps,
                applied_force_n=plant.applied_force_n,
            )
        for _ in range(round(CONTROL_S / PLANT_S)):
            chainage = ring.normalise(START_M + plant.position_m)
            plant.step(
                PLANT_S,
                force,
                gradient_permille=ring.gradient_permille(chainage),
                curve_radius_m=ring.curve_radius_m(chainage),
            )
        trace.append((now + CONTROL_S, plant.position_m, plant.speed_mps))
    return plant, trace


def _field_plan(ring: TrackMap) -> OdpPlan:
    plan, _ = plan_energy_legs(
        ring,
        URV_PARAMETERS,
        start_chainage_m=START_M,
        stops=[(1775.0, 300.0, 300.0)],
        cap_mps=CAP_MPS,
    )
    return plan


def test_a_new_speed_restriction_is_obeyed_and_the_stop_still_reached() -> None:
    """At t = 60 s a TSR of 20 km/h is set over 900–1200 m of the leg (chainage 1100–1400):
    the replanned train runs through it at most at 20 km/h and still stops at the stop."""
    ring = TrackMap(load_seed_line("bologna-ring"))
    tsr = TemporarySpeedRestriction(id="works", start_m=1100.0, end_m=1400.0, speed_mps=20 / 3.6)

    def new_restriction(now: float, plant: PointMassModel) -> OdpPlan:
        ring.add_temporary_speed_restriction(tsr)
        return replan_from_state(
            ring,
            URV_PARAMETERS,
            now_s=now,
            start_chainage_m=START_M,
            distance_m=plant.position_m,
            speed_mps=plant.speed_mps,
            stop_distance_m=1775.0 - plant.position_m,
            cruise_mps=CAP_MPS,
            arrival_s=330.0,
        )

    plant, trace = _drive(
        ring, _field_plan(ring), until_s=345.0, event_s=60.0, on_event=new_restriction
    )
    assert max(v for _, d, v in trace if 900.0 <= d <= 1200.0) <= 20 / 3.6
    assert plant.speed_mps == 0.0
    assert abs(plant.position_m - 1775.0) <= 0.5


def test_an_obstacle_reported_ahead_stops_the_train_before_it() -> None:
    ring = TrackMap(load_seed_line("bologna-ring"))
    obstacle: list[float] = []

    def obstacle_ahead(now: float, plant: PointMassModel) -> OdpPlan:
        obstacle.append(plant.position_m + 250.0)  # seen 250 m ahead
        return replan_from_state(
            ring,
            URV_PARAMETERS,
            now_s=now,
            start_chainage_m=START_M,
            distance_m=plant.position_m,
            speed_mps=plant.speed_mps,
            stop_distance_m=250.0 - EOA_MARGIN_M,
            cruise_mps=plant.speed_mps,
        )

    plant, _ = _drive(ring, _field_plan(ring), until_s=200.0, event_s=90.0, on_event=obstacle_ahead)
    assert plant.speed_mps == 0.0
    assert obstacle[0] - EOA_MARGIN_M - 1.0 <= plant.position_m < obstacle[0]


def test_after_an_etcs_intervention_the_train_is_replanned_to_its_stop() -> None:
    """The ETCS brakes for 6 s at t = 100 s; at its release AD replans from the measured
    state and reaches the stop on time."""
    ring = TrackMap(load_seed_line("bologna-ring"))

    def released(now: float, plant: PointMassModel) -> OdpPlan:
        return replan_from_state(
            ring,
            URV_PARAMETERS,
            now_s=now,
            start_chainage_m=START_M,
            distance_m=plant.position_m,
            speed_mps=plant.speed_mps,
            stop_distance_m=1775.0 - plant.position_m,
            cruise_mps=CAP_MPS,
            arrival_s=300.0,
        )

    plant, trace = _drive(
        ring, _field_plan(ring), until_s=310.0, event_s=100.0, on_event=released, braking_s=6.0
    )
    slowest = min(v for t, _, v in trace if 100.0 <= t <= 106.5)
    assert slowest < 6.0  # the intervention did slow the train
    stopped = [t for t, d, v in trace if v == 0.0 and abs(d - 1775.0) <= 0.5]
    assert stopped
    assert abs(stopped[0] - 300.0) <= 2.0
    assert abs(plant.position_m - 1775.0) <= 0.5
