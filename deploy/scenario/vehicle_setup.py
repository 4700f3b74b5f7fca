"""The vehicle of a whole-stack run, built from the scenario before it starts.

The scenario's vehicle table and the faults that live in the vehicle's own parts (its sensors,
the UDP link to the sensor fusion, the balise reader, the wheels, the Vital Control's relay and
tachometer) become the node's :class:`~onboard.node.OnboardSettings`; the faults injected while
the run goes on are ``deploy.scenario.fault_injector``'s.
"""

from __future__ import annotations

from pathlib import Path

from deploy.scenario.run_context import RunOptions, ScenarioRunError
from deploy.scenario.schema import (
    BaliseMissed,
    Fault,
    OdometerFailure,
    RelayFault,
    ScenarioSpec,
    SensorDropout,
    TachometerFault,
    UdpLinkFault,
    WheelDiameterError,
)
from onboard.node import OnboardSettings
from onboard.plant.sensors import SensorFaults, TimeWindow
from onboard.sfa.chain import SensorSettings
from onboard.sfa.link import LinkFaults
from onboard.vc import hardware as vc_hardware
from onboard.vc.installation import VcFaults

__all__ = ["VC_DATALOG", "onboard_settings", "sensor_settings", "vc_faults"]

W_PER_KW = 1000.0
VC_DATALOG = "vc-datalog.jsonl"
"""The VC's datalog in a run's report directory (``ato vc replay`` reads it)."""


def onboard_settings(
    spec: ScenarioSpec, options: RunOptions, seed: int, scratch: Path
) -> OnboardSettings:
    """The node's settings for the scenario's vehicle, with its faults, seeded."""
    vehicle = spec.vehicle
    if options.report_dir is not None and vehicle.vc_datalog:
        options.report_dir.mkdir(parents=True, exist_ok=True)
    return OnboardSettings(
        vehicle_id=vehicle.id,
        fidelity=vehicle.fidelity,
        start_position_m=vehicle.start_position_m,
        energy_plans=vehicle.energy_plans,
        vc_replicas=vehicle.vc_replicas,
        vc_faults=vc_faults(spec.faults),
        initial_soc=vehicle.initial_soc,
        range_extender_power_w=(
            None if vehicle.range_extender_kw is None else vehicle.range_extender_kw * W_PER_KW
        ),
        vc_datalog=((options.report_dir or scratch) / VC_DATALOG if vehicle.vc_datalog else None),
        sensors=sensor_settings(spec.faults, seed),
    )


def sensor_settings(faults: tuple[Fault, ...], seed: int) -> SensorSettings:
    """The emulated sensors and their UDP link with the scenario's faults, seeded."""
    outages: dict[str, list[TimeWindow]] = {"imu": [], "odometer": [], "gps": []}
    stuck: list[TimeWindow] = []
    for fault in faults:
        if isinstance(fault, SensorDropout):
            outages[fault.sensor].append(TimeWindow(fault.start_s, fault.end_s))
        elif isinstance(fault, OdometerFailure):
            window = TimeWindow(fault.start_s, fault.end_s)
            (outages["odometer"] if fault.mode == "silent" else stuck).append(window)
    link = LinkFaults()
    udp = [fault for fault in faults if isinstance(fault, UdpLinkFault)]
    if len(udp) > 1:
        raise ScenarioRunError("one udp_link fault per scenario")
    if udp:
        fault = udp[0]
        link = LinkFaults(
            loss_rate=fault.loss,
            reorder_rate=fault.reorder,
            duplicate_rate=fault.duplicate,
            corrupt_rate=fault.corrupt,
            faults_from_s=max(fault.start_s, link.faults_from_s),
            faults_until_s=fault.end_s,
        )
    diameters = [fault.error for fault in faults if isinstance(fault, WheelDiameterError)]
    if len(diameters) > 1:
        raise ScenarioRunError("one wheel_diameter fault per scenario")
    missed = frozenset(
        group
        for fault in faults
        if isinstance(fault, BaliseMissed)
        for group in fault.balise_group_ids
    )
    return SensorSettings(
        seed=seed,
        link=link,
        wheel_diameter_error=diameters[0] if diameters else None,
        missed_balise_groups=missed,
        faults=SensorFaults(
            imu_outages=tuple(outages["imu"]),
            odometer_outages=tuple(outages["odometer"]),
            gps_outages=tuple(outages["gps"]),
            odometer_stuck_at_zero=tuple(stuck),
        ),
    )


def vc_faults(faults: tuple[Fault, ...]) -> VcFaults:
    relay = [
        vc_hardware.RelayFault(start_s=f.start_s, end_s=f.end_s)
        for f in faults
        if isinstance(f, RelayFault)
    ]
    tachometer = [
        vc_hardware.TachometerFault(
            mode=vc_hardware.TachometerFaultMode(f.mode), start_s=f.start_s, end_s=f.end_s
        )
        for f in faults
        if isinstance(f, TachometerFault)
    ]
    return VcFaults(relay=relay, tachometer=tachometer)
