"""The control's energy (issue 22): an EoA short of the stop is planned for only once within
reach, so that an MA extended in the meantime leaves the journey's plan as it was."""

from __future__ import annotations

import pytest

from onboard.adf.journey import JourneyPlan, JourneyStop
from onboard.adf.odp import OdpPlan
from onboard.adf.odp_energy import plan_energy_legs
from onboard.adf.progress import JourneyProgress
from onboard.adf.replanning import LegReplanner
from onboard.plant import URV_PARAMETERS
from trackdb import TrackMap, load_seed_line

START_M = 200.0
CAP_MPS = 40 / 3.6
STOPS = [(1775.0, 300.0, 320.0), (3200.0, 550.0, 570.0), (6050.0, 1000.0, 1000.0)]


@pytest.fixture(scope="module")
def plan() -> OdpPlan:
    ring = TrackMap(load_seed_line("bologna-ring"))
    plan, kept_plain = plan_energy_legs(
        ring, URV_PARAMETERS, start_chainage_m=START_M, stops=STOPS, cap_mps=CAP_MPS
    )
    assert kept_plain == 0
    return plan


def _replanner(plan: OdpPlan) -> LegReplanner:
    stops = tuple(
        JourneyStop(name, distance, arrival, departure, name == "north")
        for name, (distance, arrival, departure) in zip(
            ("east", "south", "north"), STOPS, strict=True
        )
    )
    progress = JourneyProgress()
    progress.start(JourneyPlan("field-test", 1, START_M, stops, plan, 0), 0.0, position_m=START_M)
    replanner = LegReplanner(plan.track_map, URV_PARAMETERS, progress)
    replanner.start()
    return replanner


def test_an_eoa_short_of_the_stop_is_planned_for_once_within_reach(plan: OdpPlan) -> None:
    replanner = _replanner(plan)
    now_s = 100.0
    travelled, speed = plan.reference(now_s)
    position = START_M + travelled
    eoa_m = 1500.0  # short of east (1775 m): 630 m ahead
    replanner.set_etcs_limits(60 / 3.6, eoa_m - travelled, position_m=position)
    assert replanner.follow_authority(now_s, position, speed) is None
    assert replanner.eoa_stop_m is None  # the journey's plan runs on
    # 10 s at the cap and the braking at 0.35 m/s² from it: about 290 m.
    travelled = eoa_m - 250.0
    position = START_M + travelled
    replanner.set_etcs_limits(60 / 3.6, eoa_m - travelled, position_m=position)
    replanned = replanner.follow_authority(now_s, position, speed)
    assert replanned is not None
    assert replanner.eoa_stop_m is not None
    assert replanner.eoa_stop_m < eoa_m
