"""The wheel-sensor odometer: pulses, speed, A_est, slip and slide, and its accuracy law."""

from __future__ import annotations

import math

import pytest
from numpy.testing import assert_allclose

from onboard.etcs import (
    SUBSET_041_ACCURACY,
    URV_ODOMETER,
    EtcsInputError,
    Odometer,
    OdometerParameters,
    TrainDataError,
    WheelAdhesion,
)
from onboard.plant.readings import WheelReading
from tests.onboard.etcs.wheels import WheelRig, WheelSpeeds


def _reading(time_s: float, front_m: float, rear_m: float | None = None) -> WheelReading:
    rear = front_m if rear_m is None else rear_m
    return WheelReading(time_s, front_m, rear, 0.0, 0.0)


def _run(
    odometer: Odometer,
    rig: WheelRig,
    duration_s: float,
    acceleration_mps2: float = 0.0,
    wheels: WheelSpeeds | None = None,
) -> list[tuple[float, float, WheelAdhesion, float, float, float]]:
    """(true travel, counted, adhesion, over, under, speed error) after each reading."""
    start_m = rig.position_m - odometer.output.distance_m
    if not odometer.output.time_s and odometer.output.distance_m == 0.0:
        odometer.update([rig.reading(rig.speed_mps, rig.speed_mps)])
    trace = []
    for _ in range(round(duration_s / 0.01)):
        if wheels is None:
            reading, _ = rig.advance(acceleration_mps2)
        else:
            reading, _ = rig.advance(acceleration_mps2, wheels)
        out = odometer.update([reading])
        trace.append(
            (
                rig.position_m - start_m,
                out.distance_m,
                out.adhesion,
                out.slip_slide_over_m,
                out.slip_slide_under_m,
                out.speed_mps - rig.speed_mps,
            )
        )
    return trace


def test_the_urv_pulse_generator_and_its_accuracy_law() -> None:
    # 200 pulses per turn of a 0.92 m wheel: 69.2 pulses/m, 14.4 mm a pulse.
    assert URV_ODOMETER.pulses_per_metre == pytest.approx(200 / (math.pi * 0.92))
    assert URV_ODOMETER.pulse_m == pytest.approx(0.01445, abs=1e-5)
    assert URV_ODOMETER.speed_resolution_mps == pytest.approx(0.0723, abs=1e-4)
    law = URV_ODOMETER.accuracy()
    assert law.proportional_error == pytest.approx(0.03)  # 2 % diameter + 1 % creep
    assert law.fixed_error_m == pytest.approx(2.0 + 2 * URV_ODOMETER.pulse_m)
    assert law.within(SUBSET_041_ACCURACY)
    with pytest.raises(TrainDataError):
        OdometerParameters(diameter_tolerance=0.045)  # 5.5 % > SUBSET-041's 5 %
    with pytest.raises(TrainDataError):
        OdometerParameters(pulses_per_revolution=0)
    with pytest.raises(TrainDataError):
        OdometerParameters(speed_window_s=float("nan"))


def test_quantisation_floors_each_channel_into_pulses() -> None:
    odometer = Odometer()
    pulse_m = URV_ODOMETER.pulse_m
    odometer.update([_reading(0.0, 0.3 * pulse_m, 0.7 * pulse_m)])  # the zero: pulses 0 and 0
    out = odometer.update([_reading(0.01, 2.99 * pulse_m, 3.01 * pulse_m)])
    assert (out.pulses_front, out.pulses_rear) == (2, 3)
    assert out.distance_m == pytest.approx(2.5 * pulse_m)
    # Over a run the count stays within a pulse of the truth, and the speed within its quantum.
    rig = WheelRig(position_m=0.0, speed_mps=20.0)
    trace = _run(Odometer(), rig, 10.0)
    assert max(abs(counted - true) for true, counted, *_ in trace) <= 2 * pulse_m
    speed_errors = [error for *_, error in trace[25:]]
    assert max(abs(e) for e in speed_errors) <= URV_ODOMETER.speed_resolution_mps + 1e-9


def test_a_two_percent_diameter_error_reads_two_percent_long() -> None:
    rig = WheelRig(position_m=0.0, speed_mps=30.0, reads_long_front=0.02, reads_long_rear=0.02)
    trace = _run(Odometer(), rig, 70.0)
    true_m, counted_m, adhesion, over_m, under_m, _ = trace[-1]
    assert true_m == pytest.approx(2_100.0)
    assert_allclose(counted_m, 1.02 * true_m, atol=2 * URV_ODOMETER.pulse_m)
    assert abs(counted_m - true_m) <= URV_ODOMETER.accuracy().error_m(counted_m)
    assert (adhesion, over_m, under_m) == (WheelAdhesion.ROLLING, 0.0, 0.0)


def test_speed_and_acceleration_estimates() -> None:
    odometer, rig = Odometer(), WheelRig(position_m=0.0, speed_mps=5.0)
    _run(odometer, rig, 3.0, acceleration_mps2=1.0)
    out = odometer.output
    # The speed is the pulses of the last 0.2 s: it lags half a window behind.
    assert_allclose(out.speed_mps, rig.speed_mps - 0.1, atol=0.08)
    assert_allclose(out.acceleration_mps2, 1.0, atol=0.2)
    _run(odometer, rig, 2.0, acceleration_mps2=-1.5)
    assert_allclose(odometer.output.acceleration_mps2, -1.5, atol=0.2)


def test_no_slip_seen_at_the_vehicle_limits_with_mismatched_wheels() -> None:
    # Front reads 2 % long, rear 2 % short: the axles disagree by 4 % and nothing slips.
    rig = WheelRig(position_m=0.0, speed_mps=0.0, reads_long_front=0.02, reads_long_rear=-0.02)
    odometer = Odometer()
    trace = _run(odometer, rig, 30.0, acceleration_mps2=1.85)  # full traction, to 55 m/s
    trace += _run(odometer, rig, 40.0, acceleration_mps2=-0.93 - 0.34)  # EB and uphill
    assert {adhesion for _, _, adhesion, *_ in trace} == {WheelAdhesion.ROLLING}


def _rear_spins_up(start_s: float, end_s: float, rate_mps2: float) -> WheelSpeeds:
    def wheels(time_s: float, speed_mps: float) -> tuple[float, float]:
        spun_s = min(max(time_s - start_s, 0.0), end_s - start_s) if time_s < end_s else 0.0
        return speed_mps, speed_mps + rate_mps2 * spun_s

    return wheels


def test_a_slipping_axle_is_seen_and_the_lower_axle_gives_the_speed() -> None:
    rig = WheelRig(position_m=0.0, speed_mps=10.0)
    odometer = Odometer()
    trace = _run(odometer, rig, 1.0, acceleration_mps2=1.0)
    trace += _run(odometer, rig, 2.0, 1.0, _rear_spins_up(1.0, 3.0, 6.0))
    adhesions = [adhesion for _, _, adhesion, *_ in trace]
    assert WheelAdhesion.SLIP in adhesions[100:130]
    assert odometer.output.slip
    # The rear wheel now runs 12 m/s fast; the estimate follows the front (the ground).
    assert_allclose(odometer.output.speed_mps, rig.speed_mps, atol=0.6)
    true_m, counted_m, _, over_m, under_m, _ = trace[-1]
    assert under_m > 0.0
    # What the slip may have added is within the allowances and the rolling law.
    assert -under_m - 2.1 <= true_m - counted_m <= over_m + 2.1
    # The slip ends half a second after the wheel grips again.
    trace = _run(odometer, rig, 1.0, acceleration_mps2=1.0)
    assert trace[-1][2] is WheelAdhesion.ROLLING


def test_a_locked_slide_grows_the_allowance_ahead_to_cover_the_ground_run() -> None:
    rig = WheelRig(position_m=0.0, speed_mps=30.0)
    odometer = Odometer()
    _run(odometer, rig, 1.0)

    def locked(_time_s: float, _speed_mps: float) -> tuple[float, float]:
        return 0.0, 0.0

    # Brakes lock both wheels on a slippery rail: the train slows at only 0.3 m/s².
    trace = _run(odometer, rig, 8.0, -0.3, locked)
    assert WheelAdhesion.SLIDE in {adhesion for _, _, adhesion, *_ in trace}
    for true_m, counted_m, _, over_m, under_m, _ in trace:
        assert -under_m - 2.1 <= true_m - counted_m <= over_m + 2.1
    true_m, counted_m, _, over_m, _, _ = trace[-1]
    assert true_m - counted_m > 20.0  # the wheels no longer measure the ground
    assert over_m > true_m - counted_m


def test_position_at_a_time_is_interpolated_between_readings() -> None:
    odometer = Odometer()
    odometer.update([_reading(0.0, 0.0), _reading(0.01, 0.0)])
    odometer.update([_reading(0.02, 1.0), _reading(0.03, 2.0)])
    pulse_m = URV_ODOMETER.pulse_m
    at = odometer.position_at(0.025)
    assert_allclose(
        at.distance_m, 0.5 * (odometer.position_at(0.02).distance_m + 2.0), atol=pulse_m
    )
    assert odometer.position_at(-1.0).distance_m == 0.0  # before the first: the first
    ahead = odometer.position_at(0.05)  # after the last: on at the estimated speed
    assert ahead.distance_m == pytest.approx(
        odometer.output.distance_m + 0.02 * odometer.output.speed_mps
    )


def test_readings_out_of_order_are_refused_and_repeats_skipped() -> None:
    odometer = Odometer()
    odometer.update([_reading(0.0, 0.0), _reading(0.01, 0.1)])
    before = odometer.output
    assert odometer.update([_reading(0.01, 0.5)]) == before
    with pytest.raises(EtcsInputError):
        odometer.update([_reading(0.005, 0.2)])
    with pytest.raises(EtcsInputError):
        odometer.update([_reading(0.02, float("inf"))])
    with pytest.raises(EtcsInputError):
        odometer.position_at(float("nan"))
