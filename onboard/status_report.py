"""The ATO-OB's status report (STR) to the trackside: what the stack knows of the train now,
with the Energy Manager's reckoning (``onboard.energy_manager``)."""

from __future__ import annotations

import math

from onboard.adf.odp import OdpPlan
from onboard.stack import OnboardStack
from protocol import messages as m

__all__ = ["energy_status", "status_report"]


def status_report(
    stack: OnboardStack,
    *,
    vehicle_id: str,
    seq: int,
    now_s: float,
    acceleration_mps2: float,
    traction_force_n: float,
    target_speed_mps: float | None,
    track_data_pending: str | None = None,
) -> m.StatusReport:
    """The report numbered ``seq`` at ``now_s`` [s], from the stack's estimate and state, the
    sensor fusion's acceleration [m/s²], the drives' feedback [N] and the remote driver's target
    speed [m/s] (None unless remote driving is selected)."""
    etcs = stack.etcs.output
    journey = stack.track_database.journey
    driving = stack.driving
    position_m, speed_mps = stack.position_m, stack.speed_mps
    next_stop = driving.next_stop(position_m) if driving.journey else None
    intervention = stack.etcs.intervention_speed_mps()
    return m.StatusReport(
        vehicle_id=vehicle_id,
        seq=seq,
        sim_time_s=now_s,
        line_id=stack.track_map.line.id,
        position_m=stack.track_map.normalise(position_m),
        speed_mps=speed_mps,
        acceleration_mps2=acceleration_mps2,
        traction_force_n=traction_force_n,
        ato_state=stack.ato_state,
        etcs_mode=stack.etcs.mode,
        sc_state=driving.state,
        supervision_status=etcs.supervision_status,
        target_speed_mps=target_speed_mps,
        journey_id=None if journey is None else journey.journey_id,
        position_confidence_m=max(etcs.odometry.over_reading_m, etcs.odometry.under_reading_m),
        next_timing_point_id=None if next_stop is None else next_stop.timing_point_id,
        arrivals=tuple(
            m.ArrivalEstimate(
                timing_point_id=stop.timing_point_id,
                scheduled_s=stop.arrival_s,
                estimated_s=estimate,
            )
            for stop, estimate in driving.arrival_estimates(now_s, position_m)
        ),
        vital_control=stack.vital_status(),
        permitted_speed_mps=max(etcs.permitted_speed_mps, 0.0),
        intervention_speed_mps=intervention if math.isfinite(intervention) else None,
        reference_speed_mps=driving.reference_speed_mps(now_s),
        train_hold=driving.hold,
        track_data_version=stack.track_database.onboard_version,
        track_data_pending=track_data_pending,
        energy=energy_status(stack, now_s),
    )


def energy_status(stack: OnboardStack, now_s: float) -> m.EnergyStatus:
    """The Energy Manager's reckoning at ``now_s`` [s] on the plan followed (the accepted one
    before the journey starts), for the status report."""
    driving, keeper = stack.driving, stack.journey
    plan: OdpPlan | None
    if keeper.started and driving.autonomous is not None:
        plan, journey_s = driving.autonomous.plan, driving.journey_time_s(now_s)
    else:
        plan, journey_s = (None if keeper.plan is None else keeper.plan.plan), 0.0
    reckoning = stack.energy.assess(plan, journey_s)
    available = None
    if reckoning.battery_available_j is not None:
        available = reckoning.battery_available_j + (reckoning.range_extender_available_j or 0.0)
    return m.EnergyStatus(
        soc=_finite(reckoning.soc),
        energy_to_go_j=_finite(reckoning.energy_to_go_j),
        energy_available_j=_finite(available),
        margin_j=_finite(reckoning.margin_j),
        range_extender_share=_finite(reckoning.range_extender_share),
        short=keeper.energy_short or reckoning.short,
        slowed=keeper.slowed_for_energy,
    )


def _finite(value: float | None) -> float | None:
    """A figure for the report, None when it is not a number (a report must never fail)."""
    return value if value is not None and math.isfinite(value) else None
