"""The onboard stack without a network: journey review, operator requests, RBC MAs."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from onboard.commands import command_refusal
from onboard.plant import URV_PARAMETERS, PointMassModel
from onboard.stack import OnboardStack
from protocol import messages as m
from trackdb import TrackMap, load_seed_line

RING = TrackMap(load_seed_line("bologna-ring"))


@dataclass
class StandingLocator:
    """A localisation that has the train standing where it was put, and takes fixes."""

    position_m: float
    speed_mps: float = 0.0
    acceleration_mps2: float = 0.0
    localisation_valid: bool = True

    def fix(self, chainage_m: float, detected_s: float) -> None:
        del detected_s
        self.position_m = chainage_m


def stack(line: TrackMap = RING, position_m: float = 300.0) -> OnboardStack:
    limits = PointMassModel(URV_PARAMETERS).force_limits_n
    result = OnboardStack(
        line,
        StandingLocator(position_m),
        URV_PARAMETERS,
        limits,
        start_position_m=position_m,
        energy_plans=False,
    )
    result.track_database.record_trackside_version(
        m.LineVersionReply(line_id=line.line.id, version=line.version)
    )
    return result


def profile(arrival_s: float, *, vehicle: str = "URV1", version: int = 1) -> m.JourneyProfile:
    point = m.TimingPoint(
        id="east",
        position_m=1975.0,
        kind=m.TimingPointKind.STOPPING,
        arrival_time_s=arrival_s,
        end_of_journey=True,
    )
    return m.JourneyProfile(
        vehicle_id=vehicle,
        journey_id="j",
        version=version,
        status=m.JourneyProfileStatus.VALID,
        line_id="bologna-ring",
        track_data_version=RING.version,
        max_speed_mps=40 / 3.6,
        timing_points=(point,),
    )


def test_a_journey_whose_leg_cannot_be_run_in_time_is_rejected_with_the_reason() -> None:
    onboard = stack()
    accepted, reason = onboard.review_journey(profile(arrival_s=60.0))
    assert not accepted
    assert reason is not None
    assert "infeasible" in reason
    assert onboard.journey_plan is None
    assert onboard.track_database.journey is None
    assert onboard.review_journey(profile(arrival_s=300.0)) == (True, None)
    assert onboard.journey_plan is not None
    assert onboard.journey_plan.stops[0].distance_m == pytest.approx(1975.0 - 300.0)


def test_a_journey_on_other_track_data_is_rejected() -> None:
    onboard = stack()
    other = profile(300.0).model_copy(update={"track_data_version": "0" * 64})
    accepted, reason = onboard.review_journey(other)
    assert not accepted
    assert reason == "journey planned on other track data"


def test_requests_are_refused_with_reasons_in_the_wrong_state() -> None:
    onboard = stack()
    engage = command_refusal(onboard, m.EngageCommand())
    assert engage is not None
    assert "no journey profile" in engage
    onboard.review_journey(profile(300.0))
    onboard.step_etcs(0.0)
    onboard.step_control(0.0)
    engage = command_refusal(onboard, m.EngageCommand())
    assert engage is not None
    assert "not ready" in engage
    assert command_refusal(onboard, m.DisengageCommand()) == "ATO-OB is not engaged"
    fast = command_refusal(onboard, m.RemoteDrivingTargetCommand(target_speed_mps=60.0))
    assert fast is not None
    assert "above line speed" in fast


def _issued(line: TrackMap, extent: m.MovementAuthorityExtent) -> m.MovementAuthorityMessage:
    """The RBC's first MA for URV1 on ``line``, issued at 0 s."""
    return m.MovementAuthorityMessage(
        vehicle_id="URV1",
        ma_id=1,
        change=m.MovementAuthorityChange.ISSUED,
        issued_at_s=0.0,
        line_id=line.line.id,
        line_version=line.version,
        authority=extent,
    )


def test_an_rbc_movement_authority_reaches_etcs() -> None:
    line = TrackMap(load_seed_line("milano-bologna"))
    onboard = stack(line, position_m=1000.0)
    onboard.step_etcs(0.0)
    message = _issued(line, m.MovementAuthorityExtent(start_m=1000.0, end_of_authority_m=6000.0))
    assert onboard.receive_movement_authority(message, 0.1) == "new"
    output = onboard.etcs.step_on_sensors(0.2, [])  # standing at its start
    assert output.end_of_authority_distance_m == pytest.approx(5000.0, abs=1.0)
    revoked = message.model_copy(
        update={"ma_id": 2, "authority": None, "change": m.MovementAuthorityChange.REVOKED}
    )
    assert onboard.receive_movement_authority(revoked, 0.3) == "revoked: emergency stop"


def test_skip_stop_and_train_hold_are_checked_against_the_journey() -> None:
    onboard = stack()
    assert command_refusal(onboard, m.TrainHoldCommand(hold=True)) == "no journey profile accepted"
    assert command_refusal(onboard, m.SkipStopCommand(timing_point_id="east")) == (
        "no journey profile accepted"
    )
    onboard.review_journey(profile(300.0))
    last = command_refusal(onboard, m.SkipStopCommand(timing_point_id="east"))
    assert last == "east ends the journey: it cannot be skipped"
    unknown = command_refusal(onboard, m.SkipStopCommand(timing_point_id="nowhere"))
    assert unknown == "nowhere is not a stopping point ahead on the journey"
    assert command_refusal(onboard, m.TrainHoldCommand(hold=True)) is None
    onboard.train_hold(True, 0.0)
    assert onboard.driving.hold


def test_an_rbc_speed_restriction_lowers_the_mrsp_until_revoked() -> None:
    onboard = stack(TrackMap(load_seed_line("bologna-ring")))
    track_map = onboard.track_map
    before = track_map.mrsp_mps(1200.0)
    tsr = m.SpeedRestrictionMessage(
        vehicle_id="URV1",
        restriction_id="works",
        line_id="bologna-ring",
        start_m=1100.0,
        end_m=1400.0,
        speed_mps=20 / 3.6,
    )
    assert "works" in onboard.receive_speed_restriction(tsr, 10.0)
    assert track_map.mrsp_mps(1200.0) == pytest.approx(20 / 3.6, abs=1e-9)
    assert track_map.mrsp_mps(1500.0) == pytest.approx(before, abs=1e-9)
    revoked = tsr.model_copy(update={"speed_mps": None})
    assert "revoked" in onboard.receive_speed_restriction(revoked, 20.0)
    assert track_map.mrsp_mps(1200.0) == pytest.approx(before, abs=1e-9)
    with pytest.raises(ValueError, match="line"):
        onboard.receive_speed_restriction(tsr.model_copy(update={"line_id": "other"}), 30.0)


@pytest.mark.parametrize("valid", [True, False])
def test_the_adf_locates_the_eoa_from_the_fused_position_not_from_etcs_odometry(
    valid: bool,
) -> None:
    """ETCS's distance to the EoA is measured from its estimated front end, which drifts with
    its odometry (5.4 m ahead of the truth, 1.5 km past a balise group, in a generated run);
    the ADF stops for the EoA, a place on the track, measured from its own localisation. Here
    ETCS reads 6 m ahead of the fused position: the ADF's EoA is ETCS's location of it, not
    6 m short. Without a valid localisation ETCS's distance is what there is."""
    line = TrackMap(load_seed_line("milano-bologna"))
    onboard = stack(line, position_m=1000.0)
    locator = onboard.locator
    assert isinstance(locator, StandingLocator)
    locator.position_m, locator.localisation_valid = 994.0, valid
    extent = m.MovementAuthorityExtent(
        start_m=1000.0, end_of_authority_m=1400.0, danger_point_m=200.0
    )
    message = _issued(line, extent)
    onboard.step_etcs(0.0)
    assert onboard.receive_movement_authority(message, 0.1) == "new"
    onboard.step_etcs(0.2)
    onboard.step_control(0.2)
    output = onboard.etcs.output
    assert output is not None
    assert output.end_of_authority_distance_m == pytest.approx(400.0, abs=0.5)
    eoa_at_m = onboard.driving.replanner.eoa_at_m
    assert eoa_at_m == pytest.approx(1400.0 if valid else 1394.0, abs=0.5)
