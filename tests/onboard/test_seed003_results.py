"""Seed 003 §7.3–7.4 reproduced on the bogie model in closed loop with the VCU.

(3) acceleration with the front/rear torque split, both directions; braking in three phases with
the total braking torque following the demand. (4) a sharp friction drop: the wheels' measured
speed departs from the true speed, the VCU cuts and recovers torque, and after the patch the
vehicle accelerates as on dry rail. Each manoeuvre runs once per module (about 3 s in all).
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from deploy.bench.vcu_manoeuvres import (
    FRICTION_DROP_FORCE_N,
    ManoeuvreRecord,
    acceleration_manoeuvre,
    braking_manoeuvre,
    friction_drop_manoeuvre,
    run_manoeuvre,
)
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS as BOGIE
from onboard.vcu import VcuParameters, electric_share, leading_share, vcu_parameters_for

pytestmark = pytest.mark.scenario

VCU = vcu_parameters_for(BOGIE)
MAX_TORQUE_NM = BOGIE.motor_max_torque_nm
STEPS_PER_S = 100


@pytest.fixture(scope="module")
def forwards() -> ManoeuvreRecord:
    return run_manoeuvre(acceleration_manoeuvre(1))


@pytest.fixture(scope="module")
def reverse() -> ManoeuvreRecord:
    return run_manoeuvre(acceleration_manoeuvre(-1))


@pytest.fixture(scope="module")
def braking() -> ManoeuvreRecord:
    return run_manoeuvre(braking_manoeuvre())


@pytest.fixture(scope="module")
def friction_drop() -> ManoeuvreRecord:
    return run_manoeuvre(friction_drop_manoeuvre())


@pytest.fixture(scope="module")
def dry_rail() -> ManoeuvreRecord:
    return run_manoeuvre(friction_drop_manoeuvre(adhesion=False))


def test_the_vcu_is_tuned_to_the_bogie() -> None:
    assert VcuParameters().wheel_radius_m == BOGIE.wheel_radius_m
    assert VCU.max_motor_torque_nm == BOGIE.motor_max_torque_nm
    assert VCU.max_motor_power_w == BOGIE.motor_max_power_w
    assert VCU.brake_gain_nm_per_pa == BOGIE.brake_gain_m3
    assert VCU.max_brake_pressure_pa == BOGIE.brake_max_pressure_pa


# -- (3) acceleration --------------------------------------------------------------------------


def test_acceleration_starts_on_the_trailing_axle_alone(forwards: ManoeuvreRecord) -> None:
    trailing, leading = forwards.motor_torque_rear_nm, forwards.motor_torque_front_nm
    # Below the split's start speed and before the trailing axle reaches its maximum, the
    # leading axle carries nothing (0.8 m/s: 1 m/s less four sigma of the fused speed's noise;
    # 400 N·m: the torque ramp of 4.6 kN·m/s times the motors' 0.05 s lag, with a margin).
    alone = (forwards.speed_mps < 0.8) & (trailing < MAX_TORQUE_NM - 400.0)
    assert alone.sum() > STEPS_PER_S
    assert np.abs(leading[alone]).max() == pytest.approx(0.0, abs=1e-6)
    assert trailing[alone].max() > 0.9 * MAX_TORQUE_NM
    # The leading axle starts once the trailing one is at its maximum (here before 1 m/s).
    first = int(np.argmax(leading > 10.0))
    assert trailing[first] == pytest.approx(MAX_TORQUE_NM, abs=400.0)


def test_acceleration_split_follows_k_d(forwards: ManoeuvreRecord) -> None:
    trailing, leading = forwards.motor_torque_rear_nm, forwards.motor_torque_front_nm
    total = trailing + leading
    steady = (forwards.time_s > 2.5) & (forwards.speed_mps < 7.8)
    expected = [
        max(leading_share(v, VCU), 1.0 - MAX_TORQUE_NM / t)
        for v, t in zip(forwards.speed_mps[steady], total[steady], strict=True)
    ]
    assert_allclose(leading[steady] / total[steady], expected, atol=0.02)
    # Equal torques above the threshold speed (8 m/s).
    equal = forwards.speed_mps > VCU.equal_split_speed_mps + 0.3
    assert equal.sum() > 3 * STEPS_PER_S
    assert_allclose(leading[equal], trailing[equal], atol=1.0)
    assert_allclose(total[equal], 20_000.0 * BOGIE.wheel_radius_m, rtol=1e-3)
    assert not (forwards.slip_front.any())
    assert not (forwards.slip_rear.any())
    assert forwards.speed_mps[-1] == pytest.approx(15.8, abs=0.3)


def test_reverse_acceleration_mirrors_forwards(
    forwards: ManoeuvreRecord, reverse: ManoeuvreRecord
) -> None:
    # In reverse the front axle trails: it takes the starting torque, with negative sign.
    assert_allclose(reverse.speed_mps, forwards.speed_mps, atol=0.01)
    assert_allclose(reverse.motor_torque_front_nm, -forwards.motor_torque_rear_nm, atol=5.0)
    assert_allclose(reverse.motor_torque_rear_nm, -forwards.motor_torque_front_nm, atol=5.0)
    assert reverse.motor_torque_front_nm[STEPS_PER_S] < -1000.0
    assert reverse.motor_torque_rear_nm[STEPS_PER_S] == pytest.approx(0.0, abs=1e-6)


# -- (3) braking -------------------------------------------------------------------------------


def _phase_by_speed(record: ManoeuvreRecord, margin_mps: float = 0.2) -> dict[str, object]:
    speed = record.speed_mps
    blend, low = VCU.blending_speed_mps, VCU.min_electric_braking_speed_mps
    return {
        "electric": (speed > blend + margin_mps) & (record.time_s > 1.2),
        "blended": (speed < blend - margin_mps) & (speed > low + margin_mps),
        "pneumatic": speed < low - margin_mps,
    }


def test_braking_goes_through_three_phases_in_order(braking: ManoeuvreRecord) -> None:
    masks = _phase_by_speed(braking)
    for phase, mask in masks.items():
        assert isinstance(mask, np.ndarray)
        assert mask.sum() > STEPS_PER_S
        assert set(braking.braking_phase[mask]) == {phase}
    starts = [float(braking.time_s[np.argmax(braking.braking_phase == p)]) for p in masks]
    assert starts == sorted(starts)
    assert braking.speed_mps[-1] < 0.05
    assert braking.distance_m[-1] == pytest.approx(159.0, abs=3.0)


def test_braking_torque_follows_the_demand_by_phase(braking: ManoeuvreRecord) -> None:
    masks = _phase_by_speed(braking)
    electric, pneumatic = braking.electric_braking_torque_nm, braking.pneumatic_braking_torque_nm
    demand = braking.braking_demand_nm
    total = electric + pneumatic
    e, b, p = (np.asarray(masks[name]) for name in ("electric", "blended", "pneumatic"))
    # Phase 1: the motors alone.
    assert_allclose(electric[e], demand[e], rtol=0.01)
    assert np.abs(pneumatic[e]).max() == pytest.approx(0.0, abs=1e-6)
    # Phase 2: k_e falls with speed; the brake cylinders' 0.5 s lag leaves the total ~7 % short.
    shares = [electric_share(v, 0.5, VCU) for v in braking.speed_mps[b]]
    assert_allclose(electric[b] / demand[b], shares, atol=0.03)
    assert np.all((total[b] / demand[b] > 0.90) & (total[b] / demand[b] < 1.01))
    # Phase 3: pneumatic alone, on the demand once the pressure has settled (3 lags).
    assert np.abs(electric[p]).max() < 0.001 * demand[p].max()
    settled = p & (braking.time_s > braking.time_s[np.argmax(p)] + 1.5)
    assert_allclose(total[settled], demand[settled], rtol=0.02)
    # The electric phase recharged the batteries.
    assert braking.soc.max() - braking.soc[0] > 2.5e-3
    assert braking.battery_power_w[e].min() < -150_000.0


# -- (4) friction drop -------------------------------------------------------------------------


def _patch(record: ManoeuvreRecord) -> tuple[int, int]:
    inside = np.flatnonzero(record.adhesion_factor < 1.0)
    return int(inside[0]), int(inside[-1]) + 1


def test_wheel_speed_departs_and_slip_is_detected(friction_drop: ManoeuvreRecord) -> None:
    start, end = _patch(friction_drop)
    wheel = np.maximum(friction_drop.wheel_speed_front_mps, friction_drop.wheel_speed_rear_mps)
    departure = wheel - friction_drop.speed_mps
    assert departure[:start].max() < 0.03
    assert departure[start:end].max() > 0.5
    slips = friction_drop.slip_front | friction_drop.slip_rear
    assert not slips[:start].any()
    onsets = np.flatnonzero(slips[1:] & ~slips[:-1]) + 1
    assert 2 <= len(onsets) <= 8
    assert np.all((onsets >= start) & (onsets < end))


def test_the_vcu_cuts_then_ramps_the_slipping_axle(friction_drop: ManoeuvreRecord) -> None:
    torque = friction_drop.motor_torque_front_nm
    onsets = np.flatnonzero(friction_drop.slip_front[1:] & ~friction_drop.slip_front[:-1]) + 1
    assert len(onsets) >= 2
    per_axle = FRICTION_DROP_FORCE_N / 2.0 * BOGIE.wheel_radius_m
    for onset in onsets:
        # Cut to (almost) nothing within the 0.3 s hold, then ramped back.
        cut = torque[onset : onset + 30]
        assert cut.min() < 0.02 * MAX_TORQUE_NM
        after = torque[onset + 30 : onset + 130]
        assert after[-1] > after[0] + 0.1 * MAX_TORQUE_NM
    # Once off the patch the axle is back on the demand within 2 s.
    _, end = _patch(friction_drop)
    assert torque[end + 2 * STEPS_PER_S] == pytest.approx(per_axle, rel=1e-3)


def test_after_the_patch_the_vehicle_accelerates_as_on_dry_rail(
    friction_drop: ManoeuvreRecord, dry_rail: ManoeuvreRecord
) -> None:
    _, end = _patch(friction_drop)
    after = slice(end + 150, end + 350)
    wheel = friction_drop.wheel_speed_front_mps[after]
    assert_allclose(wheel, friction_drop.speed_mps[after], atol=0.03)
    assert not (friction_drop.slip_front[after].any())
    assert not (friction_drop.slip_rear[after].any())
    speed = friction_drop.speed_mps
    acceleration = (speed[end + 350] - speed[end + 150]) / 2.0
    v0, v1 = speed[end + 150], speed[end + 350]
    dry_speed, dry_time = dry_rail.speed_mps, dry_rail.time_s
    dry_acceleration = (v1 - v0) / float(
        np.interp(v1, dry_speed, dry_time) - np.interp(v0, dry_speed, dry_time)
    )
    assert acceleration == pytest.approx(dry_acceleration, rel=0.02)
    assert acceleration > 0.9
    # The patch cost speed: about 1.3 m/s behind the dry run at the end.
    assert dry_rail.speed_mps[-1] - speed[-1] == pytest.approx(1.3, abs=0.3)
    # The true speed never falls: the rear (loaded) axle keeps pulling through the patch.
    assert np.diff(speed).min() > -1e-3
