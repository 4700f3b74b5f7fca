"""The ADF as the node runs it: RD, then a journey in AD, ETCS limits, the fallback stop."""

from __future__ import annotations

import pytest

from onboard.adf.function import DrivingFunction, NoJourneyError
from onboard.adf.journey import JourneyPlan, plan_journey
from onboard.adf.odp import InfeasibleLegError
from onboard.etcs.braking import BrakingModel, Limit, Target, TargetKind
from onboard.etcs.odometer import OdometerParameters
from onboard.plant import URV_PARAMETERS, PointMassModel
from onboard.plant.point_mass import with_model_mismatch
from protocol import messages as m
from protocol.messages import ScState
from trackdb import TrackMap, load_seed_line
from trackdb.schema import TemporarySpeedRestriction

pytestmark = pytest.mark.scenario

CONTROL_S, PLANT_S = 0.2, 0.01


def field_journey(version: int = 1) -> m.JourneyProfile:
    """Seed 000's field test from 200 m: east (1975 m), south (3400 m), north (550 m)."""
    points = (
        m.TimingPoint(
            id="east",
            position_m=1975.0,
            kind=m.TimingPointKind.STOPPING,
            arrival_time_s=300.0,
            departure_time_s=320.0,
        ),
        m.TimingPoint(
            id="south",
            position_m=3400.0,
            kind=m.TimingPointKind.STOPPING,
            arrival_time_s=550.0,
            departure_time_s=570.0,
        ),
        m.TimingPoint(
            id="north",
            position_m=550.0,
            kind=m.TimingPointKind.STOPPING,
            arrival_time_s=1000.0,
            end_of_journey=True,
        ),
    )
    return m.JourneyProfile(
        vehicle_id="URV1",
        journey_id="field-test",
        version=version,
        status=m.JourneyProfileStatus.VALID,
        line_id="bologna-ring",
        track_data_version="x",
        max_speed_mps=40 / 3.6,
        timing_points=points,
    )


class Loop:
    """The function on a mismatched point-mass plant, in lockstep."""

    def __init__(self, ring: TrackMap, start_m: float = 0.0) -> None:
        self.ring = ring
        self.adf = DrivingFunction(ring, URV_PARAMETERS)
        self.plant = PointMassModel(with_model_mismatch(URV_PARAMETERS), position_m=start_m)
        self.now = 0.0

    def gradient(self) -> float:
        return self.ring.gradient_permille(self.ring.normalise(self.plant.position_m))

    def run(self, seconds: float, **flags: bool) -> None:
        for _ in range(round(seconds / CONTROL_S)):
            force = self.adf.step(
                self.now,
                position_m=self.plant.position_m,
                speed_mps=self.plant.speed_mps,
                applied_force_n=self.plant.applied_force_n,
                gradient_permille=self.gradient(),
                force_limits_n=self.plant.force_limits_n(self.plant.speed_mps),
                **flags,
            )
            for _ in range(round(CONTROL_S / PLANT_S)):
                chainage = self.ring.normalise(self.plant.position_m)
                self.plant.step(
                    PLANT_S,
                    force,
                    gradient_permille=self.ring.gradient_permille(chainage),
                    curve_radius_m=self.ring.curve_radius_m(chainage),
                )
            self.now += CONTROL_S


@pytest.fixture(scope="module")
def ring() -> TrackMap:
    return TrackMap(load_seed_line("bologna-ring"))


def test_remote_driving_then_the_first_leg_of_the_journey_in_ad(ring: TrackMap) -> None:
    loop = Loop(ring)
    with pytest.raises(NoJourneyError):
        loop.adf.engage(0.0)
    loop.adf.remote(30 / 3.6, 0.0, speed_mps=0.0, gradient_permille=loop.gradient())
    loop.run(40.0)
    assert loop.plant.speed_mps == pytest.approx(30 / 3.6, abs=0.3)
    loop.adf.remote(0.0, loop.now, speed_mps=loop.plant.speed_mps, gradient_permille=0.0)
    loop.run(25.0)
    assert loop.plant.speed_mps == 0.0
    start = ring.normalise(loop.plant.position_m)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=start)
    assert [s.timing_point_id for s in journey.stops] == ["east", "south", "north"]
    assert journey.stops[-1].end_of_journey
    assert journey.legs_kept_plain == 0
    loop.adf.start_journey(journey, loop.now, position_m=loop.plant.position_m)
    loop.adf.engage(loop.now)
    loop.run(2.2)
    assert loop.adf.state is ScState.AD  # after the 2 s hand-over
    started = loop.now
    loop.run(305.0)
    stop = loop.adf.stopped_at(loop.plant.position_m, loop.plant.speed_mps)
    assert stop is not None
    assert stop.timing_point_id == "east"
    assert abs(ring.normalise(loop.plant.position_m) - 1975.0) <= 0.5
    assert loop.now - started > 300.0
    assert loop.adf.next_stop(loop.plant.position_m).timing_point_id == "south"  # type: ignore[union-attr]


def test_the_train_closes_up_to_an_eoa_short_of_its_stop_then_goes_on(ring: TrackMap) -> None:
    loop = Loop(ring, start_m=200.0)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=200.0)
    loop.adf.start_journey(journey, 0.0, position_m=200.0)
    loop.adf.engage(0.0)
    standstills: list[float] = []
    while not (loop.plant.speed_mps == 0.0 and loop.plant.position_m > 785.0):
        # ETCS permits the line speed up to the EoA at chainage 800, before the first stop;
        # its distance ahead shrinks as the train runs.
        loop.adf.set_etcs_limits(
            60 / 3.6, 800.0 - loop.plant.position_m, position_m=loop.plant.position_m
        )
        loop.run(CONTROL_S)
        left = loop.plant.position_m > 200.5  # the departure prepared, it stands a step first
        if (
            left
            and loop.plant.speed_mps == 0.0
            and not any(abs(x - loop.plant.position_m) < 0.5 for x in standstills)
        ):
            standstills.append(loop.plant.position_m)
        assert loop.now < 250.0
    loop.adf.set_etcs_limits(
        60 / 3.6, 800.0 - loop.plant.position_m, position_m=loop.plant.position_m
    )
    loop.run(10.0)  # it stays
    # First short of it by the 5 m margin plus what is kept for the growth of the odometry
    # interval: 6 % of the distance to the EoA when the stop was planned, once the train could
    # reach its braking within 10 s (about 300 m at the cap: 17–19 m); standing there, the
    # anticipation has shrunk with the distance left: it closes up to the 5 m margin.
    assert 774.0 <= standstills[0] <= 779.0
    assert loop.adf.stopping_for_authority
    assert 791.0 <= loop.plant.position_m <= 795.5
    assert 800.0 - loop.plant.position_m <= 10.0
    # The route given back: on to east, on time (the schedule allows it).
    loop.adf.set_etcs_limits(60 / 3.6, None, position_m=loop.plant.position_m)
    while loop.adf.stopped_at(loop.plant.position_m, loop.plant.speed_mps) is None:
        loop.run(CONTROL_S)
        assert loop.now < 330.0
    assert not loop.adf.stopping_for_authority
    stop = loop.adf.stopped_at(loop.plant.position_m, loop.plant.speed_mps)
    assert stop is not None
    assert stop.timing_point_id == "east"
    assert abs(loop.plant.position_m - 1975.0) <= 0.5
    assert loop.now <= 300.0 + 2.0


def test_trackside_loss_replans_to_the_next_stopping_point(ring: TrackMap) -> None:
    loop = Loop(ring, start_m=200.0)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=200.0)
    loop.adf.start_journey(journey, 0.0, position_m=200.0)
    loop.adf.engage(0.0)
    loop.run(100.0)
    loop.adf.stop_at_next_stopping_point(
        loop.now, position_m=loop.plant.position_m, speed_mps=loop.plant.speed_mps
    )
    assert loop.adf.fallback_active
    loop.run(300.0)
    assert loop.plant.speed_mps == 0.0
    assert abs(loop.plant.position_m - 1975.0) <= 0.5


def test_traction_cut_and_service_brake_from_the_ato_ob_win(ring: TrackMap) -> None:
    loop = Loop(ring)
    loop.adf.remote(30 / 3.6, 0.0, speed_mps=0.0, gradient_permille=0.0)
    loop.run(10.0, traction_allowed=False)
    assert loop.plant.applied_force_n <= 0.0
    assert loop.plant.speed_mps < 0.5
    loop.run(10.0)
    assert loop.plant.speed_mps > 2.0
    loop.run(15.0, service_brake=True)
    assert loop.plant.speed_mps == 0.0


def test_a_journey_with_an_unreachable_schedule_is_refused(ring: TrackMap) -> None:
    profile = field_journey()
    rushed = profile.model_copy(
        update={
            "timing_points": (
                profile.timing_points[0].model_copy(
                    update={
                        "arrival_time_s": 60.0,
                        "departure_time_s": None,
                        "end_of_journey": True,
                    }
                ),
            )
        }
    )
    with pytest.raises(InfeasibleLegError, match="field-test"):
        plan_journey(ring, URV_PARAMETERS, rushed, start_chainage_m=200.0)


def test_a_skipped_stop_is_run_through_and_the_next_one_served(ring: TrackMap) -> None:
    loop = Loop(ring, start_m=200.0)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=200.0)
    loop.adf.start_journey(journey, 0.0, position_m=200.0)
    loop.adf.engage(0.0)
    loop.run(60.0)
    loop.adf.skip_stop(
        "east", loop.now, position_m=loop.plant.position_m, speed_mps=loop.plant.speed_mps
    )
    assert loop.adf.next_stop(loop.plant.position_m).timing_point_id == "south"  # type: ignore[union-attr]
    slowest_near_east = float("inf")
    for _ in range(int(560 / 2.0)):
        loop.run(2.0)
        if abs(loop.plant.position_m - 1975.0) < 30.0:
            slowest_near_east = min(slowest_near_east, loop.plant.speed_mps)
        if loop.adf.stopped_at(loop.plant.position_m, loop.plant.speed_mps) is not None:
            break
    assert slowest_near_east > 3.0  # ran through east
    stop = loop.adf.stopped_at(loop.plant.position_m, loop.plant.speed_mps)
    assert stop is not None
    assert stop.timing_point_id == "south"
    assert abs(loop.plant.position_m - 3400.0) <= 0.5
    loop.run(0.4)  # a control step at standstill marks the stop served
    assert [s.timing_point_id for s, _ in loop.adf.arrival_estimates(loop.now, 3400.0)] == ["north"]


def test_train_hold_keeps_the_train_at_the_stop_until_released(ring: TrackMap) -> None:
    loop = Loop(ring, start_m=200.0)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=200.0)
    loop.adf.start_journey(journey, 0.0, position_m=200.0)
    loop.adf.engage(0.0)
    loop.run(100.0)
    loop.adf.set_hold(
        True, loop.now, position_m=loop.plant.position_m, speed_mps=loop.plant.speed_mps
    )
    loop.run(300.0)  # past east's departure at 320 s
    assert loop.now > 390.0
    assert loop.plant.speed_mps == 0.0
    assert abs(loop.plant.position_m - 1975.0) <= 0.5
    loop.adf.set_hold(
        False, loop.now, position_m=loop.plant.position_m, speed_mps=loop.plant.speed_mps
    )
    loop.run(30.0)
    assert loop.plant.speed_mps > 3.0
    assert loop.plant.position_m > 2000.0


def test_no_limit_cycle_at_a_low_constant_speed_just_under_a_tsr() -> None:
    """A TSR of 25 km/h put in force inside the leg: the train settles just under it and holds
    (issue 18's "Why": it used to oscillate between 0 and 25 km/h through it)."""
    ring = TrackMap(load_seed_line("bologna-ring"))
    loop = Loop(ring, start_m=200.0)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=200.0)
    loop.adf.start_journey(journey, 0.0, position_m=200.0)
    loop.adf.engage(0.0)
    tsr = TemporarySpeedRestriction(id="tsr-1", start_m=900.0, end_m=1400.0, speed_mps=25 / 3.6)
    speeds: list[float] = []
    while loop.plant.position_m < 1400.0:
        if loop.now == pytest.approx(20.0):  # running at 40 km/h, some 500 m before it
            ring.add_temporary_speed_restriction(tsr)
            loop.adf.speed_limits_changed(
                loop.now, position_m=loop.plant.position_m, speed_mps=loop.plant.speed_mps
            )
        # ETCS's permitted speed is the MRSP where the train is (its ceiling).
        loop.adf.set_etcs_limits(
            ring.mrsp_mps(loop.plant.position_m), None, position_m=loop.plant.position_m
        )
        loop.run(CONTROL_S)
        if 950.0 <= loop.plant.position_m <= 1390.0:
            reference = loop.adf.reference_speed_mps(loop.now)
            assert reference is not None
            assert abs(loop.plant.speed_mps - reference) * 3.6 <= 0.3  # it tracks the plan
            speeds.append(loop.plant.speed_mps * 3.6)
        assert loop.now < 200.0
    assert len(speeds) > 50
    assert max(speeds) <= 25.0
    assert min(speeds) >= 20.0
    # No cycle: the speed turns (by more than 0.1 km/h) at most once, from holding just under
    # the limit to coasting towards its end (the plan's energy-saving).
    turns, direction, extreme = 0, 0, speeds[0]
    for speed in speeds:
        step = speed - extreme
        if abs(step) > 0.1 and (step > 0) != (direction > 0):
            turns += direction != 0
            direction = 1 if step > 0 else -1
        if (speed - extreme) * direction >= 0:
            extreme = speed
    assert turns <= 1


def test_a_stop_reached_late_keeps_its_dwell(ring: TrackMap) -> None:
    """A TSR that makes the train arrive at east after its scheduled departure: the replanned
    leg ends there, and the later legs wait for the dwell (issue 18: the time-based reference
    used to leave east before the train had reached it, and ran the train through it)."""
    ring = TrackMap(load_seed_line("bologna-ring"))
    loop = Loop(ring, start_m=200.0)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=200.0)
    loop.adf.start_journey(journey, 0.0, position_m=200.0)
    loop.adf.engage(0.0)
    loop.run(200.0)
    ring.add_temporary_speed_restriction(
        TemporarySpeedRestriction(id="tsr-late", start_m=1700.0, end_m=2100.0, speed_mps=8 / 3.6)
    )
    loop.adf.speed_limits_changed(
        loop.now, position_m=loop.plant.position_m, speed_mps=loop.plant.speed_mps
    )
    arrived_s = None
    while loop.now < 500.0:
        loop.adf.set_etcs_limits(
            ring.mrsp_mps(loop.plant.position_m), None, position_m=loop.plant.position_m
        )
        loop.run(CONTROL_S)
        stop = loop.adf.stopped_at(loop.plant.position_m, loop.plant.speed_mps)
        if arrived_s is None and stop is not None and stop.timing_point_id == "east":
            arrived_s = loop.now
            assert abs(loop.plant.position_m - 1975.0) <= 0.5
        if arrived_s is not None and loop.plant.speed_mps > 0.1:
            break
    assert arrived_s is not None
    assert arrived_s > 320.0
    east = journey.stops[0]
    # East's dwell, from the replanned arrival (the train stops a second or two after it).
    assert loop.adf.departure_s(east) >= arrived_s + 20.0 - 2.0
    assert loop.now >= loop.adf.departure_s(east)  # it left no earlier
    assert loop.adf.next_stop(loop.plant.position_m).timing_point_id == "south"  # type: ignore[union-attr]


def test_a_train_far_behind_its_plan_is_replanned_from_where_it_is(ring: TrackMap) -> None:
    """Held back by the brake for 15 s (as by a permitted speed that rose late), the train falls
    far behind its reference; the leg is replanned from where it is, and east is served."""
    loop = Loop(ring, start_m=200.0)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=200.0)
    loop.adf.start_journey(journey, 0.0, position_m=200.0)
    loop.adf.engage(0.0)
    loop.run(60.0)
    replans = loop.adf.replans
    loop.run(15.0, service_brake=True)
    assert loop.adf.replans == replans  # nothing to replan under the brake: ETCS's business
    loop.run(10.0)
    assert loop.adf.replans > replans
    reference = loop.adf.autonomous.plan.reference(loop.now)[0]  # type: ignore[union-attr]
    assert abs(reference - (loop.plant.position_m - 200.0)) < 5.0
    loop.run(230.0)  # to 315 s: east's arrival is at 300 s, its departure at 320 s
    stop = loop.adf.stopped_at(loop.plant.position_m, loop.plant.speed_mps)
    assert stop is not None
    assert stop.timing_point_id == "east"
    assert abs(loop.plant.position_m - 1975.0) <= 0.5


def test_a_tsr_put_in_force_during_the_fallback_stop_is_planned_for() -> None:
    """The trackside lost, the train runs to its fallback stop (east) when a TSR comes into force
    ahead (ETCS's link to the RBC is not the ATO session): the fallback's plan is redone under
    it. Issue 18, gen-1-117: the fallback's plan ran on at 58 km/h into a 25 km/h TSR and met
    ETCS's service brake."""
    ring = TrackMap(load_seed_line("bologna-ring"))
    loop = Loop(ring, start_m=200.0)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=200.0)
    loop.adf.start_journey(journey, 0.0, position_m=200.0)
    loop.adf.engage(0.0)
    loop.run(60.0)
    loop.adf.stop_at_next_stopping_point(
        loop.now, position_m=loop.plant.position_m, speed_mps=loop.plant.speed_mps
    )
    assert loop.adf.fallback_active
    assert loop.plant.position_m < 900.0
    ring.add_temporary_speed_restriction(
        TemporarySpeedRestriction(id="tsr-1", start_m=1400.0, end_m=1600.0, speed_mps=20 / 3.6)
    )
    loop.adf.speed_limits_changed(
        loop.now, position_m=loop.plant.position_m, speed_mps=loop.plant.speed_mps
    )
    assert loop.adf.fallback_active  # still the fallback: to its stop, unscheduled
    plan = loop.adf.autonomous.plan  # type: ignore[union-attr]
    samples = [plan.reference(loop.now + 0.5 * k) for k in range(1000)]
    inside = [speed for distance, speed in samples if 1200.0 <= distance <= 1400.0]
    assert inside
    assert max(inside) <= 20 / 3.6
    assert samples[-1] == pytest.approx((1775.0, 0.0), abs=1e-6)  # east, the fallback's stop


def _standing_at_east() -> tuple[TrackMap, DrivingFunction, JourneyPlan]:
    """A fresh ring, and the ADF engaged on the field journey from 200 m, standing at east."""
    ring = TrackMap(load_seed_line("bologna-ring"))
    adf = DrivingFunction(ring, URV_PARAMETERS)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=200.0)
    adf.start_journey(journey, 0.0, position_m=200.0)
    adf.engage(0.0)
    adf.progress.update_served(200.0 + journey.stops[0].distance_m, speed_mps=0.0)  # arrived
    return ring, adf, journey


def test_a_leg_replanned_while_the_train_stands_at_a_stop_leaves_after_its_dwell() -> None:
    """A TSR comes into force on the next leg as the train stands at east, before east's
    departure (320 s): the replanned leg leaves at the departure, not at once. Issue 18,
    gen-1-152: the reference left a dwell (24 s) ahead of the train, which could not catch up
    (ETCS's permitted speed under the MRSP up to the TSR)."""
    ring, adf, journey = _standing_at_east()
    east = journey.stops[0]
    at_east = 200.0 + east.distance_m
    assert adf.next_stop(at_east).timing_point_id == "south"  # type: ignore[union-attr]
    ring.add_temporary_speed_restriction(
        TemporarySpeedRestriction(id="tsr-2", start_m=2300.0, end_m=2500.0, speed_mps=20 / 3.6)
    )
    adf.speed_limits_changed(302.0, position_m=at_east, speed_mps=0.0)
    plan = adf.autonomous.plan  # type: ignore[union-attr]
    assert plan.legs[0].start_s == pytest.approx(adf.departure_s(east))
    assert plan.reference(319.9) == pytest.approx((east.distance_m, 0.0))
    assert plan.reference(330.0)[0] > east.distance_m + 1.0
    assert plan.end_s == pytest.approx(journey.plan.end_s)  # the rest of the journey on time


def test_a_tsr_put_in_force_in_one_leg_is_planned_for_in_the_later_legs_it_lies_on() -> None:
    """A TSR comes into force during the first leg (200 → east) over 2300–2500 m, on the second
    leg (east → south): the first leg is replanned at once, and the second, planned under the
    old limits at the journey's acceptance, as it begins (at east). Issue 18, gen-1-83: a TSR of
    the first leg met again a lap on, in the third leg, whose plan ran at 58 km/h into it and
    met ETCS's service brake twice."""
    ring = TrackMap(load_seed_line("bologna-ring"))
    adf = DrivingFunction(ring, URV_PARAMETERS)
    journey = plan_journey(ring, URV_PARAMETERS, field_journey(), start_chainage_m=200.0)
    adf.start_journey(journey, 0.0, position_m=200.0)
    adf.engage(0.0)
    ring.add_temporary_speed_restriction(
        TemporarySpeedRestriction(id="tsr-4", start_m=2300.0, end_m=2500.0, speed_mps=20 / 3.6)
    )
    adf.speed_limits_changed(60.0, position_m=600.0, speed_mps=10.0)
    east = journey.stops[0]
    at_east = 200.0 + east.distance_m

    def second_leg_speeds() -> list[float]:
        plan = adf.autonomous.plan  # type: ignore[union-attr]
        samples = [plan.reference(320.0 + 0.5 * k) for k in range(460)]
        return [speed for distance, speed in samples if 2100.0 <= distance <= 2300.0]

    assert max(second_leg_speeds()) > 20 / 3.6 + 1.0  # still the old plan: the TSR unknown
    adf.progress.update_served(at_east, speed_mps=0.0)  # arrived at east
    assert adf.next_stop(at_east).timing_point_id == "south"  # type: ignore[union-attr]
    replans = adf.replans
    plan = adf.replanner.renew_stale_leg(302.0, at_east, 0.0)
    assert plan is not None
    adf._drive(plan)
    assert adf.replans == replans + 1
    assert second_leg_speeds()
    assert max(second_leg_speeds()) <= 20 / 3.6
    assert plan.legs[0].start_s == pytest.approx(adf.departure_s(east))
    assert adf.replanner.renew_stale_leg(303.0, at_east, 0.0) is None  # once


def test_behind_its_plan_the_train_keeps_under_a_target_speed_by_etcs_over_read() -> None:
    """Issue 18, gen-1-137: a TSR of 20 km/h 59 m ahead of where the journey starts; the train
    leaves 1.2 s after its reference and catches up at its ceiling. Up to the TSR ETCS's
    permitted speed comes down to 20 km/h, and once its max-safe front end is a metre or two
    short of the TSR its target speed monitoring brakes at any speed it reads above that: its
    windowed speed reads up to a pulse per window high. The NMPC's ceiling from the permitted
    speed is held ETCS's over-read share (2 %) under it: the train keeps under by more than
    that pulse (it ran at 19.78 km/h, 0.6 % under, and ETCS braked)."""
    ring = TrackMap(load_seed_line("bologna-ring"))
    tsr = TemporarySpeedRestriction(id="tsr-3", start_m=276.5, end_m=553.5, speed_mps=20 / 3.6)
    ring.add_temporary_speed_restriction(tsr)
    north = m.TimingPoint(
        id="north",
        position_m=550.0,
        kind=m.TimingPointKind.STOPPING,
        arrival_time_s=73.7,
        end_of_journey=True,
    )
    profile = field_journey().model_copy(
        update={"timing_points": (north,), "max_speed_mps": 32 / 3.6}
    )
    decrease = Target(TargetKind.SPEED_DECREASE, tsr.start_m, tsr.speed_mps)
    limits = BrakingModel().target_limits(decrease, track_map=ring, from_m=0.0)
    loop = Loop(ring, start_m=217.8)
    journey = plan_journey(ring, URV_PARAMETERS, profile, start_chainage_m=217.8)
    loop.adf.start_journey(journey, 0.0, position_m=217.8)
    loop.adf.engage(0.0)
    interval_m = 18.0  # ETCS's max-safe front end runs this far ahead (as in gen-1-137)
    last_metres_kmh: list[float] = []
    while loop.plant.position_m < tsr.start_m:
        front_m = loop.plant.position_m + interval_m
        # ETCS's permitted speed: the TSR's braking curve until the max-safe front end reaches
        # it, the lowest MRSP under the train from there on.
        permitted = min(ring.mrsp_mps(loop.plant.position_m), ring.mrsp_mps(front_m))
        if front_m < tsr.start_m:
            curve = limits.speed_mps(Limit.PERMITTED, tsr.start_m - front_m)
            permitted = min(permitted, max(curve, tsr.speed_mps))
        loop.adf.set_etcs_limits(permitted, None, position_m=loop.plant.position_m)
        loop.run(CONTROL_S, service_brake=loop.now < 1.2)
        if 0.0 < tsr.start_m - (loop.plant.position_m + interval_m) <= 5.0:
            last_metres_kmh.append(loop.plant.speed_mps * 3.6)
        assert loop.now < 60.0
    assert last_metres_kmh
    pulse_kmh = OdometerParameters().speed_resolution_mps * 3.6  # 0.26 km/h
    assert max(last_metres_kmh) <= 20.0 - pulse_kmh


def test_a_leg_capped_by_the_permitted_speed_is_replanned_when_it_rises() -> None:
    """A TSR of 20 km/h over east (1767–2011 m) comes into force as the train stands there: the
    leg to south is replanned with ETCS's permitted speed (20 km/h, the train inside the TSR) as
    its cap, and replanned again, at the journey's cap, once the permitted speed has risen (the
    train's rear out of the TSR). Issue 18, gen-1-430: the capped leg ran the 4 km to the next
    stop at 19.5 km/h and missed it."""
    ring, adf, journey = _standing_at_east()
    east = journey.stops[0]
    at_east = 200.0 + east.distance_m
    ring.add_temporary_speed_restriction(
        TemporarySpeedRestriction(id="tsr-5", start_m=1767.5, end_m=2011.5, speed_mps=20 / 3.6)
    )
    adf.set_etcs_limits(20 / 3.6, None, position_m=at_east)
    adf.speed_limits_changed(302.0, position_m=at_east, speed_mps=0.0)

    def top_speed_beyond_tsr() -> float:
        plan = adf.autonomous.plan  # type: ignore[union-attr]
        samples = [plan.reference(320.0 + 0.5 * k) for k in range(460)]
        return max(speed for distance, speed in samples if distance >= 2100.0 - 200.0)

    assert top_speed_beyond_tsr() <= 20 / 3.6  # capped at the permitted speed
    capped = adf.autonomous.plan  # type: ignore[union-attr]
    assert capped.legs[0].end_s > journey.stops[1].arrival_s + 10.0  # late at south
    assert adf.replanner.released(330.0, 2005.0, 20 / 3.6) is None  # still inside
    adf.set_etcs_limits(80 / 3.6, None, position_m=2030.0)
    plan = adf.replanner.released(332.0, 2030.0, 19.5 / 3.6)
    assert plan is not None
    adf._drive(plan)
    assert top_speed_beyond_tsr() > 20 / 3.6 + 1.0  # no longer capped
    south = journey.stops[1]
    assert plan.legs[0].end_s <= south.arrival_s + 1e-6  # back on schedule
    assert adf.replanner.released(333.0, 2040.0, 25 / 3.6) is None  # once
