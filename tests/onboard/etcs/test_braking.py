"""Braking curves and limits against independent numbers (reference_braking.py), gradients."""

from __future__ import annotations

import math
from dataclasses import replace
from functools import cache

import pytest
from numpy.testing import assert_allclose

from onboard.etcs import (
    BrakeModelType,
    BrakingCapabilityError,
    BrakingModel,
    DecelerationProfile,
    EtcsInputError,
    Limit,
    NationalValues,
    Target,
    TargetKind,
    TargetLimits,
    TrainData,
    braking_times,
    dv_ebi_mps,
    dv_sbi_mps,
    dv_warning_mps,
    speed_measurement_accuracy_mps,
)
from onboard.etcs.deceleration import gradient_steps, lowest_gradient_under_train
from onboard.etcs.values import URV_TRAIN_DATA, conversion_model_build_up_times_s
from protocol.units import MPS_PER_KMH
from tests.onboard.etcs import reference_braking as ref
from trackdb import LineBuilder, TrackMap

EOA_M = 15_000.0
SVL_KEYS = {
    Limit.EBD: "ebd",
    Limit.EBI: "ebi",
    Limit.SBI2: "sbi2",
    Limit.WARNING: "w_svl",
    Limit.PERMITTED: "p_svl",
    Limit.INDICATION: "i_svl",
}
EOA_KEYS = {
    Limit.SBD: "sbd",
    Limit.SBI1: "sbi1",
    Limit.WARNING: "w_eoa",
    Limit.PERMITTED: "p_eoa",
    Limit.INDICATION: "i_eoa",
}


@cache
def _uniform_line(gradient_permille: float) -> TrackMap:
    builder = LineBuilder(id="uniform", name="Uniform gradient")
    builder.straight(20_000.0, speed_kmh=200.0, gradient_permille=gradient_permille)
    return TrackMap(builder.build(geodetic_step_m=500.0))


def _limits(kind: TargetKind, gradient_permille: float) -> TargetLimits:
    return BrakingModel().target_limits(
        Target(kind, EOA_M), track_map=_uniform_line(gradient_permille), from_m=0.0
    )


@pytest.mark.parametrize("gradient_permille", [0.0, -10.0])
@pytest.mark.parametrize("acceleration_mps2", [0.0, 0.3])
def test_stop_curves_at_160_kmh_match_the_reference(
    gradient_permille: float, acceleration_mps2: float
) -> None:
    expected = ref.stop_curves(160.0, gradient_permille, acceleration_mps2)
    speed = 160.0 * MPS_PER_KMH
    for kind, keys in (
        (TargetKind.SUPERVISED_LOCATION, SVL_KEYS),
        (TargetKind.END_OF_AUTHORITY, EOA_KEYS),
    ):
        limits = _limits(kind, gradient_permille)
        assert set(limits.limits) == set(keys)
        for limit, key in keys.items():
            distance = limits.distance_m(limit, speed, acceleration_mps2=acceleration_mps2)
            assert_allclose(distance, expected[key], rtol=1e-9, atol=1e-6, err_msg=key)
            # The speed of each curve at that distance is 160 km/h again.
            back = limits.speed_mps(limit, distance, acceleration_mps2=acceleration_mps2)
            assert_allclose(back, speed, atol=1e-5, err_msg=key)


def test_documented_numbers_are_pinned() -> None:
    """The reference's printout for the two documented cases (docs/etcs.md)."""
    level, downhill = ref.stop_curves(160.0, 0.0), ref.stop_curves(160.0, -10.0)
    assert_allclose(
        [level["ebd"], level["ebi"], level["sbi2"], level["p_svl"], level["i_svl"]],
        [1316.872, 1442.261, 1508.928, 1686.706, 2086.706],
        atol=1e-3,
    )
    assert_allclose(
        [downhill["ebd"], downhill["ebi"], downhill["sbi2"], downhill["p_svl"], downhill["sbd"]],
        [1510.582, 1647.683, 1714.350, 1892.128, 1635.667],
        atol=1e-3,
    )
    limits = _limits(TargetKind.SUPERVISED_LOCATION, -10.0)
    assert_allclose(limits.distance_m(Limit.EBI, 160.0 * MPS_PER_KMH), 1647.683, atol=1e-3)


@pytest.mark.parametrize("speed_kmh", [100.0, 160.0, 210.0])
def test_ceiling_margins_match_the_reference(speed_kmh: float) -> None:
    speed = speed_kmh * MPS_PER_KMH
    assert_allclose(dv_ebi_mps(speed), ref.dv_ebi_kmh(speed_kmh) * MPS_PER_KMH, atol=1e-12)
    assert_allclose(dv_sbi_mps(speed), ref.dv_sbi_kmh(speed_kmh) * MPS_PER_KMH, atol=1e-12)
    assert_allclose(dv_warning_mps(speed), ref.dv_warning_kmh(speed_kmh) * MPS_PER_KMH, atol=1e-12)


def test_ceiling_margins_documented_values() -> None:
    table = {100.0: (7.5, 5.5, 4.0), 160.0: (11.25, 7.75, 5.0), 210.0: (15.0, 10.0, 5.0)}
    for speed_kmh, margins_kmh in table.items():
        speed = speed_kmh * MPS_PER_KMH
        got = [
            dv_ebi_mps(speed) / MPS_PER_KMH,
            dv_sbi_mps(speed) / MPS_PER_KMH,
            dv_warning_mps(speed) / MPS_PER_KMH,
        ]
        assert_allclose(got, margins_kmh, atol=1e-9)


def test_speed_accuracy_law() -> None:
    for speed_kmh in (0.0, 30.0, 160.0, 500.0, 600.0):
        got = speed_measurement_accuracy_mps(speed_kmh * MPS_PER_KMH) / MPS_PER_KMH
        assert_allclose(got, ref.v_ura_kmh(speed_kmh), atol=1e-9)


def test_limits_are_ordered_and_grow_with_speed() -> None:
    limits = _limits(TargetKind.SUPERVISED_LOCATION, 0.0)
    previous = None
    for speed_kmh in range(0, 201, 10):
        d = limits.distances(speed_kmh * MPS_PER_KMH)
        assert d.emergency_brake_intervention_m is not None
        order = [
            d.emergency_brake_intervention_m,
            d.service_brake_intervention_m,
            d.warning_m,
            d.permitted_m,
            d.indication_m,
        ]
        assert order == sorted(order)
        if previous is not None:
            assert d.permitted_m > previous
        previous = d.permitted_m


def test_mrsp_target_ebd_crosses_target_speed_plus_dv_ebi_at_the_target() -> None:
    model = BrakingModel()
    target = Target(TargetKind.SPEED_DECREASE, 5_000.0, 80.0 * MPS_PER_KMH)
    limits = model.target_limits(target)
    assert_allclose(limits.curve.speed_mps(0.0), (80.0 + 7.5) * MPS_PER_KMH, atol=1e-12)
    # Level track: V² = V_t² + 2·A_safe·d.
    expected = math.sqrt(((80.0 + 7.5) * MPS_PER_KMH) ** 2 + 2 * model.a_brake_safe_mps2 * 1000.0)
    assert_allclose(limits.speed_mps(Limit.EBD, 1000.0), expected, atol=1e-9)
    # The permitted speed never falls below the target speed when the supervision floors it,
    # and the P limit is ahead of the EBI's.
    assert limits.distance_m(Limit.PERMITTED, 120 * MPS_PER_KMH) > limits.distance_m(
        Limit.EBI, 120 * MPS_PER_KMH
    )


def test_gradient_changes_apply_with_the_train_length() -> None:
    """Level, then +10 ‰ from 5000 m, then −10 ‰ from 8000 m: the uphill counts only once the
    whole train is on it; the downhill as soon as the front end is."""
    builder = LineBuilder(id="steps", name="Gradient steps")
    builder.straight(5_000.0, speed_kmh=160.0)
    builder.straight(3_000.0, speed_kmh=160.0, gradient_permille=10.0)
    builder.straight(4_000.0, speed_kmh=160.0, gradient_permille=-10.0)
    track_map = TrackMap(builder.build(geodetic_step_m=500.0))
    length = URV_TRAIN_DATA.length_m
    steps = lowest_gradient_under_train(gradient_steps(track_map, 0.0, 12_000.0), length)
    assert steps == [
        (0.0, 5_000.0 + length, 0.0),
        (5_000.0 + length, 8_000.0, 10.0),
        (8_000.0, 12_000.0, -10.0),
    ]
    model = BrakingModel()
    limits = model.target_limits(
        Target(TargetKind.SUPERVISED_LOCATION, 9_000.0), track_map=track_map, from_m=0.0
    )
    a_level = model.a_brake_safe_mps2
    a_up = a_level + 9.81 * 10.0 / (1000.0 + 150.0)
    a_down = a_level - 9.81 * 10.0 / (1000.0 + 20.0)
    # From the SvL back: 1000 m downhill, 2990 m uphill, then level.
    square = 2 * (a_down * 1000.0 + a_up * (3_000.0 - length) + a_level * 500.0)
    distance = 1000.0 + (3_000.0 - length) + 500.0
    assert_allclose(limits.curve.speed_mps(distance), math.sqrt(square), rtol=1e-12)
    assert_allclose(limits.distance_m(Limit.EBD, math.sqrt(square)), distance, rtol=1e-12)


def test_ring_gradient_steps_run_across_the_origin() -> None:
    builder = LineBuilder(id="ring", name="Ring", ring=True)
    for _ in range(4):
        builder.straight(500.0, speed_kmh=60.0, gradient_permille=2.0)
        builder.curve(500.0, 318.31, speed_kmh=40.0, gradient_permille=-2.0)
    track_map = TrackMap(builder.build(geodetic_step_m=50.0))
    steps = gradient_steps(track_map, 3_800.0, 4_700.0)
    assert steps == [(3_800.0, 4_000.0, -2.0), (4_000.0, 4_500.0, 2.0), (4_500.0, 4_700.0, -2.0)]


def test_steep_downhill_defeats_the_brakes() -> None:
    builder = LineBuilder(id="steep", name="Steep")
    builder.straight(5_000.0, speed_kmh=100.0, gradient_permille=-90.0)
    track_map = TrackMap(builder.build(geodetic_step_m=500.0))
    target = Target(TargetKind.SUPERVISED_LOCATION, 4_000.0)
    with pytest.raises(BrakingCapabilityError):
        BrakingModel().target_limits(target, track_map=track_map, from_m=0.0)
    with pytest.raises(BrakingCapabilityError):
        DecelerationProfile([0.0, 10.0], [0.5, -0.1])


def test_braking_times_of_the_urv_and_of_a_lambda_train() -> None:
    times = braking_times(URV_TRAIN_DATA)
    assert (times.t_traction_s, times.t_berem_s, times.t_bs2_s) == (0.0, 1.0, 1.5)
    assert times.t_indication_s == 9.0
    t_eb, t_sb = conversion_model_build_up_times_s(400.0)
    assert_allclose((t_eb, t_sb), (2.30 + 0.17 * 16, 3.0 + 6.0 + 1.6), atol=1e-12)
    lambda_train = TrainData(
        length_m=400.0,
        max_speed_mps=160 * MPS_PER_KMH,
        brake_model=BrakeModelType.LAMBDA,
        a_brake_emergency_mps2=1.0,
        a_brake_service_mps2=0.8,
        t_brake_emergency_s=t_eb,
        t_brake_service_s=t_sb,
        t_traction_cut_off_s=3.0,
        traction_cut_off_implemented=False,
    )
    national = NationalValues()
    at_zero = braking_times(lambda_train, national=national)
    above_zero = braking_times(lambda_train, national=national, target_speed_mps=20.0)
    assert_allclose(at_zero.t_be_s, 1.1 * t_eb, atol=1e-12)
    assert_allclose(above_zero.t_be_s, 1.1 * 1.2 * t_eb, atol=1e-12)
    assert at_zero.t_traction_s == 3.0
    assert_allclose(BrakingModel(lambda_train).a_brake_safe_mps2, 0.7 * 0.9, atol=1e-12)
    no_service = braking_times(replace(URV_TRAIN_DATA, service_brake_available=False))
    assert (no_service.t_bs1_s, no_service.t_bs2_s) == (0.0, 0.0)


def test_a_target_has_only_its_own_limits() -> None:
    eoa = _limits(TargetKind.END_OF_AUTHORITY, 0.0)
    with pytest.raises(EtcsInputError):
        eoa.distance_m(Limit.EBI, 10.0)
    svl = _limits(TargetKind.SUPERVISED_LOCATION, 0.0)
    with pytest.raises(EtcsInputError):
        svl.speed_mps(Limit.SBD, 100.0)
    with pytest.raises(EtcsInputError):
        svl.distance_m(Limit.EBI, -1.0)
    with pytest.raises(EtcsInputError):
        svl.speed_mps(Limit.EBI, math.nan)


@pytest.mark.parametrize("inhibit_compensation", [False, True])
def test_the_bisection_limit_function_is_the_limit_arithmetic_bit_for_bit(
    inhibit_compensation: bool,
) -> None:
    """``speed_mps`` bisects on a compiled copy of ``_limit_m``: the same bits everywhere
    (the curve's gradient bands, V_ura's three pieces, accelerations either side of A_est2's
    cap, below and above an MRSP target's speed); and the compiled bisection finds the
    interpreter's speed, bisecting on ``_limit_m``, to the bit."""
    from onboard.etcs.braking import _limit_distance

    builder = LineBuilder(id="steps", name="Gradient steps")
    builder.straight(5_000.0, speed_kmh=160.0)
    builder.straight(3_000.0, speed_kmh=160.0, gradient_permille=10.0)
    builder.straight(4_000.0, speed_kmh=160.0, gradient_permille=-10.0)
    track_map = TrackMap(builder.build(geodetic_step_m=500.0))
    national = NationalValues(inhibit_speed_accuracy_compensation=inhibit_compensation)
    model = BrakingModel(national=national)
    targets = [
        Target(TargetKind.END_OF_AUTHORITY, 9_000.0),
        Target(TargetKind.SUPERVISED_LOCATION, 9_500.0),
        Target(TargetKind.SPEED_DECREASE, 10_000.0, 40 * MPS_PER_KMH),
    ]
    speeds = [
        0.0,
        1e-3,
        5.0,
        30 * MPS_PER_KMH,
        30 * MPS_PER_KMH + 1e-9,
        11.0,
        40 * MPS_PER_KMH,
        90.0,
        140.0,
        600.0,
    ]
    for target in targets:
        limits = model.target_limits(target, track_map=track_map, from_m=0.0)
        for limit in limits.limits:
            if limit in (Limit.EBD, Limit.SBD):
                continue
            for acceleration in (-0.5, -0.0, 0.0, 0.2, 0.4, 1.3):
                compiled = limits._compiled(limit, acceleration)
                for speed in speeds:
                    expected = limits._limit_m(limit, speed, acceleration)
                    assert _limit_distance(speed, *compiled) == expected
                for distance_m in (-50.0, 0.0, 12.5, 400.0, 2_500.0, 9_000.0, 1e7):
                    found = limits.speed_mps(limit, distance_m, acceleration_mps2=acceleration)
                    assert found == _bisect(limits, limit, distance_m, acceleration)


def _bisect(limits: TargetLimits, limit: Limit, distance_m: float, acceleration: float) -> float:
    """``TargetLimits.speed_mps``'s bisection, interpreted, on ``_limit_m``."""

    def limit_m(v: float) -> float:
        return limits._limit_m(limit, v, acceleration)

    if limit_m(0.0) > distance_m:
        return 0.0
    low, high = 0.0, 150.0
    while limit_m(high) <= distance_m:
        low, high = high, 2.0 * high
        if high > 1e4:
            return low
    while high - low > 1e-6:
        middle = 0.5 * (low + high)
        if limit_m(middle) > distance_m:
            high = middle
        else:
            low = middle
    return low


def test_the_curve_distance_function_is_distance_m_bit_for_bit() -> None:
    """The compiled curve the bisections use gives the curve's own distances, bands and
    beyond."""
    from onboard.etcs.braking import _curve_distance

    builder = LineBuilder(id="steps", name="Gradient steps")
    builder.straight(5_000.0, speed_kmh=160.0)
    builder.straight(3_000.0, speed_kmh=160.0, gradient_permille=10.0)
    builder.straight(4_000.0, speed_kmh=160.0, gradient_permille=-10.0)
    track_map = TrackMap(builder.build(geodetic_step_m=500.0))
    target = Target(TargetKind.SPEED_DECREASE, 10_000.0, 40 * MPS_PER_KMH)
    curve = BrakingModel().target_limits(target, track_map=track_map, from_m=0.0).curve
    for speed_mps in (0.0, 5.0, 40 * MPS_PER_KMH, 11.2, 30.0, 44.4, 90.0):
        assert _curve_distance(speed_mps, curve.arrays()) == curve.distance_m(speed_mps)
