"""The Energy Manager (seed 000): its arithmetic, its check at acceptance, the status fields."""

from __future__ import annotations

import dataclasses
import math

import pytest
from numpy.testing import assert_allclose

from onboard.adf.odp import plan_legs
from onboard.energy_manager import (
    EnergyAssessment,
    EnergyManager,
    EnergyManagerParameters,
    assess_energy,
    plan_energy,
)
from onboard.journey_keeper import within_arrival_windows
from onboard.plant import URV_PARAMETERS, PointMassModel
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS
from onboard.plant.powertrain import PowertrainParameters
from onboard.plant.readings import PowertrainReading
from onboard.stack import OnboardStack
from onboard.status_report import status_report
from onboard.vcu import vcu_parameters_for
from protocol import messages as m
from protocol.units import J_PER_KWH, MPS_PER_KMH
from tests.onboard.test_stack import StandingLocator
from trackdb import TrackMap, load_seed_line

RING = TrackMap(load_seed_line("bologna-ring"))
URV = EnergyManagerParameters.for_urv()
EAST_M, SOUTH_M = 1975.0, 3400.0


def test_the_urv_s_data_come_from_its_vcu_and_powertrain() -> None:
    # 2 packs × 742 V × 105 Ah = 155.82 kWh; the floor is the VCU's sustaining threshold.
    assert URV.battery_energy_j / J_PER_KWH == pytest.approx(155.82)
    assert URV.soc_floor == 0.465
    assert URV.drive_efficiency == 0.92
    assert URV.auxiliary_power_w == 5_000.0
    assert URV.range_extender_power_w == 100_000.0
    assert URV.battery_efficiency == 0.95
    assert URV.range_extender_kg_per_j * J_PER_KWH == pytest.approx(0.235)


def test_energy_to_go_is_traction_over_the_drives_plus_the_auxiliaries() -> None:
    p = dataclasses.replace(URV, range_extender_power_w=0.0)
    # 9.2 kWh at the wheel over 0.92 = 10 kWh; 5 kW × 720 s = 1 kWh.
    a = assess_energy(p, soc=0.565, wheel_to_go_j=9.2 * J_PER_KWH, time_to_go_s=720.0)
    assert a.energy_to_go_j is not None
    assert a.traction_to_go_j is not None
    assert_allclose(a.traction_to_go_j / J_PER_KWH, 10.0, atol=1e-9)
    assert_allclose(a.energy_to_go_j / J_PER_KWH, 11.0, atol=1e-9)
    # (0.565 − 0.465) × 155.82 kWh × 0.95 = 14.8029 kWh.
    assert a.battery_available_j is not None
    assert a.margin_j is not None
    assert_allclose(a.battery_available_j / J_PER_KWH, 14.8029, atol=1e-4)
    assert_allclose(a.margin_j / J_PER_KWH, 3.8029, atol=1e-4)
    assert a.range_extender_share == 0.0
    assert not a.short


def test_the_margin_is_short_under_the_reserve_not_only_below_zero() -> None:
    p = dataclasses.replace(URV, range_extender_power_w=0.0)
    needed_kwh = 11.0
    # Batteries giving 1.05 × the need: a positive margin, but under the 10 % reserve.
    soc = p.soc_floor + 1.05 * needed_kwh * J_PER_KWH / (p.battery_energy_j * 0.95)
    a = assess_energy(p, soc=soc, wheel_to_go_j=9.2 * J_PER_KWH, time_to_go_s=720.0)
    assert a.margin_j is not None
    assert_allclose(a.margin_j / J_PER_KWH, 0.55, atol=1e-6)
    assert a.short
    soc = p.soc_floor + 1.11 * needed_kwh * J_PER_KWH / (p.battery_energy_j * 0.95)
    assert not assess_energy(p, soc=soc, wheel_to_go_j=9.2 * J_PER_KWH, time_to_go_s=720.0).short


def test_below_the_floor_the_batteries_give_nothing() -> None:
    a = assess_energy(URV, soc=0.30, wheel_to_go_j=1.0e6, time_to_go_s=100.0)
    assert a.battery_available_j == 0.0


def test_the_range_extender_gives_its_power_over_the_time_left_at_most_its_fuel() -> None:
    p = dataclasses.replace(URV, range_extender_power_w=50_000.0)
    a = assess_energy(p, soc=0.465, wheel_to_go_j=0.0, time_to_go_s=3600.0)
    assert a.range_extender_available_j == pytest.approx(50.0 * J_PER_KWH)
    assert a.range_extender_share == 1.0  # 50 kWh against 5 kWh of auxiliaries
    # 2.35 kg at 235 g/kWh is 10 kWh: the fuel, not the power, bounds it.
    fuelled = dataclasses.replace(p, range_extender_fuel_kg=2.35)
    a = assess_energy(fuelled, soc=0.465, wheel_to_go_j=0.0, time_to_go_s=3600.0)
    assert a.range_extender_available_j == pytest.approx(10.0 * J_PER_KWH)
    a = assess_energy(fuelled, soc=0.465, wheel_to_go_j=0.0, time_to_go_s=3600.0, fuel_used_kg=2.0)
    assert a.range_extender_available_j == pytest.approx(0.35 / 0.235 * J_PER_KWH)


def test_without_a_soc_the_energy_to_go_is_reported_without_a_margin() -> None:
    a = assess_energy(URV, soc=None, wheel_to_go_j=1.0e6, time_to_go_s=10.0)
    assert a.energy_to_go_j == pytest.approx(1.0e6 / 0.92 + 5.0e4)
    assert a.margin_j is None
    assert not a.short


def test_the_fuel_burnt_is_counted_from_the_extender_s_power_reports() -> None:
    manager = EnergyManager(dataclasses.replace(URV, range_extender_fuel_kg=10.0), URV_PARAMETERS)
    for k in range(11):
        manager.read(_reading(0.5, time_s=float(k) * 360.0, extender_w=100_000.0))
    # 100 kW for an hour at 235 g/kWh.
    assert manager.fuel_used_kg == pytest.approx(23.5)
    assert manager.soc == 0.5


def test_the_plan_s_energy_on_the_level_is_its_kinetic_energy_and_resistance() -> None:
    plan = plan_legs(RING, start_chainage_m=200.0, stops=[(EAST_M - 200.0, 300.0, 300.0)])
    energy = plan_energy(plan, URV_PARAMETERS, step_s=0.1)
    # Bounded by the kinetic energy at cruise plus the Davis and gradient work over the leg.
    cruise = max(plan.reference(t)[1] for t in range(300))
    mass = URV_PARAMETERS.mass_kg * (1 + URV_PARAMETERS.rotating_mass_factor)
    kinetic = 0.5 * mass * cruise**2
    assert kinetic < energy.total_j < kinetic + 1.0e6
    assert energy.to_go_j(0.0) == pytest.approx(energy.total_j)
    assert energy.to_go_j(energy.end_s) == 0.0
    assert 0.0 < energy.to_go_j(150.0) < energy.total_j


def test_the_arrival_windows_make_the_slower_profile() -> None:
    slower = within_arrival_windows(_tight_journey(window_s=60.0))
    assert slower is not None
    east, south = slower.timing_points
    assert east.arrival_time_s == 210.0
    assert east.departure_time_s == 210.0  # the dwell gives way to the window
    assert south.arrival_time_s == 360.0
    assert east.arrival_tolerance_s == south.arrival_tolerance_s == 0.0
    assert within_arrival_windows(_tight_journey(window_s=0.0)) is None


def test_a_short_margin_slows_the_plan_within_the_windows() -> None:
    onboard = _stack(soc=0.4755)
    assert onboard.review_journey(_tight_journey(window_s=60.0)) == (True, None)
    codes = [event.code for event in onboard.take_events()]
    assert codes == ["energy.slower_profile"]
    plan = onboard.journey_plan
    assert plan is not None
    assert plan.stops[-1].arrival_s == 360.0
    report = _report(onboard)
    assert report.energy is not None
    assert report.energy.slowed
    assert not report.energy.short
    assert report.energy.soc == pytest.approx(0.4755)


def test_when_even_the_slower_plan_is_short_the_operator_is_warned_at_acceptance() -> None:
    onboard = _stack(soc=0.4715)
    assert onboard.review_journey(_tight_journey(window_s=60.0)) == (True, None)
    events = onboard.take_events()
    assert [event.code for event in events] == ["energy.slower_profile", "energy.insufficient"]
    assert events[-1].severity is m.EventSeverity.WARNING
    report = _report(onboard)
    assert report.energy is not None
    assert report.energy.short
    assert report.energy.margin_j is not None


def test_enough_energy_keeps_the_timetable_s_plan_and_the_status_carries_the_figures() -> None:
    onboard = _stack(soc=0.9)
    assert onboard.review_journey(_tight_journey(window_s=60.0)) == (True, None)
    assert onboard.take_events() == []
    plan = onboard.journey_plan
    assert plan is not None
    assert plan.stops[-1].arrival_s == 300.0
    energy = _report(onboard).energy
    assert energy is not None
    assert energy.energy_to_go_j is not None
    assert energy.energy_available_j is not None
    assert energy.margin_j == pytest.approx(energy.energy_available_j - energy.energy_to_go_j)
    assert 1.0 < energy.energy_to_go_j / J_PER_KWH < 2.0
    assert not energy.short
    assert not energy.slowed
    # The report's energy survives the wire.
    wire = m.StatusReport.model_validate_json(_report(onboard).model_dump_json())
    assert wire.energy == _report(onboard).energy


def test_an_old_status_report_without_energy_is_still_valid() -> None:
    onboard = _stack(soc=0.9)
    payload = _report(onboard).model_dump(mode="json")
    del payload["energy"]
    assert m.StatusReport.model_validate(payload).energy is None


def _reading(soc: float, *, time_s: float = 0.0, extender_w: float = 0.0) -> PowertrainReading:
    return PowertrainReading(
        time_s=time_s,
        soc=soc,
        battery_voltage_v=742.0,
        battery_current_a=0.0,
        max_discharge_power_w=296_000.0,
        max_charge_power_w=296_000.0,
        continuous_current_a=210.0,
        range_extender_power_w=extender_w,
        motor_temperature_front_c=25.0,
        motor_temperature_rear_c=25.0,
    )


def _stack(*, soc: float, position_m: float = 200.0) -> OnboardStack:
    """A stack on the ring whose range extender is out of service, its SOC read as ``soc``."""
    parameters = EnergyManagerParameters.for_vehicle(
        dataclasses.replace(
            vcu_parameters_for(URV_BOGIE_PARAMETERS), range_extender_max_power_w=0.0
        ),
        PowertrainParameters(),
    )
    onboard = OnboardStack(
        RING,
        StandingLocator(position_m),
        URV_PARAMETERS,
        PointMassModel(URV_PARAMETERS).force_limits_n,
        start_position_m=position_m,
        energy=parameters,
    )
    onboard.track_database.record_trackside_version(
        m.LineVersionReply(line_id="bologna-ring", version=RING.version)
    )
    onboard.energy.read(_reading(soc))
    return onboard


def _tight_journey(*, window_s: float) -> m.JourneyProfile:
    """East then south at up to 60 km/h, the low-energy scenarios' timetable."""
    points = (
        m.TimingPoint(
            id="east",
            position_m=EAST_M,
            kind=m.TimingPointKind.STOPPING,
            arrival_time_s=150.0,
            arrival_tolerance_s=window_s,
            departure_time_s=170.0,
        ),
        m.TimingPoint(
            id="south",
            position_m=SOUTH_M,
            kind=m.TimingPointKind.STOPPING,
            arrival_time_s=300.0,
            arrival_tolerance_s=window_s,
            end_of_journey=True,
        ),
    )
    return m.JourneyProfile(
        vehicle_id="URV1",
        journey_id="low-energy",
        version=1,
        status=m.JourneyProfileStatus.VALID,
        line_id="bologna-ring",
        track_data_version=RING.version,
        max_speed_mps=60.0 * MPS_PER_KMH,
        timing_points=points,
    )


def _report(onboard: OnboardStack) -> m.StatusReport:
    return status_report(
        onboard,
        vehicle_id="URV1",
        seq=0,
        now_s=0.0,
        acceleration_mps2=0.0,
        traction_force_n=0.0,
        target_speed_mps=None,
    )


def test_a_soc_that_is_not_a_number_is_dropped_and_a_report_never_fails() -> None:
    manager = EnergyManager(URV, URV_PARAMETERS)
    manager.read(_reading(math.nan))
    assert manager.soc is None
    manager.read(_reading(0.6))
    manager.read(_reading(math.inf))
    assert manager.soc == 0.6
    onboard = _stack(soc=0.9)
    broken = EnergyAssessment(math.nan, 1.0, 1.0, math.inf, 0.0, math.nan, 0.0, False)
    onboard.energy.assess = lambda *_args: broken  # type: ignore[method-assign]
    energy = _report(onboard).energy
    assert energy is not None
    assert energy.soc is None
    assert energy.margin_j is None
    assert energy.energy_available_j is None


def test_a_margin_turning_short_while_running_warns_once() -> None:
    onboard = _stack(soc=0.9)
    assert onboard.review_journey(_tight_journey(window_s=60.0)) == (True, None)
    onboard.journey.start(0.0, 200.0)
    onboard.journey.watch_energy(1.0)
    assert onboard.take_events() == []
    onboard.energy.read(_reading(0.466, time_s=2.0))
    onboard.journey.watch_energy(2.0)
    onboard.journey.watch_energy(2.2)
    events = onboard.take_events()
    assert [event.code for event in events] == ["energy.margin_short"]
    assert events[0].severity is m.EventSeverity.WARNING
