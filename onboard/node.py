"""The ATO-OB process of one vehicle: its Zenoh seams and its table of tasks.

The node declares the vehicle's liveliness token, holds the session with the trackside
(``onboard.session``), answers trackside commands, takes journey profiles and RBC movement
authorities, publishes status and events, and runs the onboard stack (``onboard.stack``: ETCS,
ATO-OB controller, ADF), the VCU, the sensor fusion and the Vital Control on the executive.

The node is the process's composition root: it alone holds the simulated vehicle
(:class:`~onboard.plant.vehicle.SimulatedVehicle`: the dynamics and the sensor models, the only
part that reads the truth) and hands its outputs on: the interface-modules' datagrams to the
sensor fusion, the axle-end sensors' readings and the BTM's balise groups to ETCS, the VCU and
the VC, the drives' feedback to the ADF. It never reads the vehicle's state itself
(``tests/test_architecture.py`` checks which of its members the node touches).

Commands are validated and acknowledged on arrival, then executed at the next release of the
``commands`` task, so that what they change happens at a tick of simulated time.

In lockstep (a :class:`SimClock`) two exchanges are made synchronous so that a run does not
depend on how fast the wire is: the handshake waits for its answer, and the acknowledgement of
each status report sent in an open session is taken at the next status tick, one status period
later, waiting for it there (up to ``BARRIER_S`` of wall time) if it has not come: the per-link
barrier of ARCHITECTURE.md, pipelined so that the round trip overlaps the simulation. In real
time both are asynchronous.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import zenoh

from onboard.commands import CommandDesk
from onboard.energy_manager import EnergyManagerParameters
from onboard.events import StackEvent
from onboard.intake import TracksideIntake
from onboard.plant import URV_PARAMETERS, PointMassModel
from onboard.plant.balise_reader import BaliseReader, BaliseReaderFaults
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS
from onboard.plant.marker_reader import StopMarkerReader, StopMarkerReaderFaults
from onboard.plant.powertrain import PowertrainParameters
from onboard.plant.sensors import InterfaceModules
from onboard.plant.vehicle import BogiePlant, SimulatedVehicle
from onboard.plant.wheel_sensors import WheelSensors, draw_diameter_error
from onboard.ports import TracksidePorts
from onboard.runtime import Clock, Executive, SimClock
from onboard.runtime.clock import NS_PER_S
from onboard.session import SessionClient
from onboard.session_link import SessionLink
from onboard.sfa.chain import MARKER_FIX_SIGMA_M, SensorFusionChain, SensorSettings
from onboard.stack import ControlInputs, OnboardStack
from onboard.status_barrier import StatusBarrier
from onboard.status_report import status_report
from onboard.track_desk import TrackDataDesk
from onboard.vc import Datalog, DatalogRecorder, VcConfig
from onboard.vc.installation import VcFaults, VcInstallation
from onboard.vcu import VcuParameters, vcu_parameters_for
from onboard.vcu.drive import VcuDrive
from protocol import messages as m
from trackdb import TrackMap

__all__ = ["Fidelity", "NODE_VC_CONFIG", "OnboardNode", "OnboardSettings", "TASK_TABLE"]

_log = logging.getLogger(__name__)

Fidelity = Literal["point_mass", "bogie"]


@dataclass(frozen=True)
class TaskSpec:
    period_s: float
    priority: int


TASK_TABLE: dict[str, TaskSpec] = {
    "commands": TaskSpec(period_s=0.05, priority=90),
    "plant": TaskSpec(period_s=0.01, priority=80),
    "sfa": TaskSpec(period_s=0.01, priority=79),
    "etcs": TaskSpec(period_s=0.1, priority=60),
    "control": TaskSpec(period_s=0.2, priority=50),
    # The Vital Control's own tasks sit between: vc.io 40, B 30, C 20, the 2oo2 voter 15, A 10.
    "vital_link": TaskSpec(period_s=0.01, priority=8),
    "session": TaskSpec(period_s=0.1, priority=6),
    "status": TaskSpec(period_s=0.2, priority=4),
    "track_data": TaskSpec(period_s=5.0, priority=2),
}
"""The onboard tasks: period [s] and priority (higher runs first at a shared release)."""
NODE_VC_CONFIG = VcConfig(vigilance_period_s=30.0, vigilance_timeout_s=10.0)
"""⚠ A remote operator at a console is asked for vigilance every 30 s and has 10 s to answer
(the VC library's 5 s / 2 s are the seeds' bench values); both are settings."""


@dataclass(frozen=True, kw_only=True)
class OnboardSettings:
    vehicle_id: str
    line_id: str = "bologna-ring"
    start_position_m: float = 0.0
    fidelity: Fidelity = "point_mass"
    """The plant: the point-mass model, or the 10-DOF bogie model behind the VCU."""
    initial_soc: float = 0.9
    """The batteries' state of charge at start (the bogie model's powertrain)."""
    range_extender_power_w: float | None = None
    """The range extender's rated power [W], when the vehicle's differs from the URV's 100 kW
    (0: out of service); the plant, the VCU and the Energy Manager all take it."""
    sensors: SensorSettings = SensorSettings()
    """The emulated sensors, their link to the listener, and their seed. The ATO-OB and the ADF
    drive on the sensor-fusion estimate (interface-modules emulator → link → listener → OBCU
    input, in this process); ETCS on its own odometry."""
    etcs_id: int = 1
    train_length_m: float = 6.0
    energy_plans: bool = True
    """Plan journeys energy-minimised (else the plain LSPB)."""
    vital_control: bool = True
    """Fit the Vital Control (its tasks B and C run every 2 ms)."""
    vc_config: VcConfig = NODE_VC_CONFIG
    vc_replicas: int = 2
    """2 for two VC boards in 2-out-of-2 with the pair's voter and watchdog, as on the seeds'
    vehicle; 1 for a single board (comparisons, tests of the board alone)."""
    vc_faults: VcFaults = VcFaults()
    vc_datalog: Path | None = None
    """Record the VC's notifications (JSON Lines) here; ``ato vc replay`` reads them."""
    track_dir: Path | None = None
    """Keep the track data received from the trackside here, verified (None: not kept)."""


class OnboardNode:
    """One vehicle's onboard process, bound to an open Zenoh session and a clock.

    The composition root: it builds the simulated vehicle, the sensor fusion, the onboard
    stack, the VCU and the Vital Control, binds them to the trackside through
    :class:`~onboard.ports.TracksidePorts`, and registers its tasks (:data:`TASK_TABLE`) on
    the executive.
    """

    def __init__(
        self,
        settings: OnboardSettings,
        *,
        session: zenoh.Session,
        clock: Clock,
        track_map: TrackMap,
    ) -> None:
        self.settings = settings
        self.vehicle_id = settings.vehicle_id
        self.track_map = track_map
        """The line the node was built on: the plant's world. The track data on board, which
        the trackside may update, are ``stack.track_map`` (``onboard.track_desk``)."""
        self.clock = clock
        self.lockstep = isinstance(clock, SimClock)
        self.executive = Executive(clock)
        vcu_parameters, powertrain = _energy_data(settings)
        self.plant = _simulated_vehicle(settings, track_map, powertrain, start_s=clock.now_s)
        self.vcu = VcuDrive(vcu_parameters) if settings.fidelity == "bogie" else None
        vital = _vital_control(settings, lambda: _wheel_travel_m(self.plant), start_s=clock.now_s)
        self.sensor_fusion = SensorFusionChain(
            track_map, settings.sensors, start_position_m=settings.start_position_m
        )
        self.stack = OnboardStack(
            track_map,
            self.sensor_fusion,
            URV_PARAMETERS,
            self.plant.force_limits_n,
            start_position_m=settings.start_position_m,
            start_s=clock.now_s,
            energy_plans=settings.energy_plans,
            vital=vital,
            energy=EnergyManagerParameters.for_vehicle(vcu_parameters, powertrain),
        )
        self.track_database = self.stack.track_database
        self.internal_fault = False
        """An ATO-OB internal fault, injected by scenario runs: the controller goes to FA."""
        self._status_seq = 0
        self._last_report: m.StatusReport | None = None
        self._bind(session)
        self._datalog: Datalog | None = None
        self._register_tasks(vital)
        self.emit(m.EventSeverity.INFO, "onboard.started", f"line {track_map.line.id}")

    def _bind(self, session: zenoh.Session) -> None:
        """The vehicle's ports on the session, and what moves messages through them."""
        self.session_client = SessionClient(
            vehicle_id=self.vehicle_id,
            etcs_id=self.settings.etcs_id,
            train_length_m=self.settings.train_length_m,
        )
        self.commands = CommandDesk(
            self.stack, self.vehicle_id, lambda: self.clock.now_s, self.session_client.guard
        )
        self.barrier = StatusBarrier(lockstep=self.lockstep)
        self.ports = TracksidePorts(
            session,
            self.vehicle_id,
            on_command=self.commands.on_command,
            on_status_ack=self.barrier.on_ack,
            on_trackside_liveliness=self._on_trackside_liveliness,
            block_status=self.lockstep,
        )
        self.intake = TracksideIntake(
            self.ports, self.stack, self.session_client, emit=self._emit_at
        )
        self.track_data = TrackDataDesk(
            self.ports, self.stack, self.sensor_fusion, self.settings.track_dir, emit=self._emit_at
        )
        self.session_link = SessionLink(
            self.session_client,
            self.ports,
            self.barrier,
            lockstep=self.lockstep,
            emit=self._emit_at,
            on_current_authority=self.intake.on_current_authority,
        )

    def _register_tasks(self, vital: VcInstallation | None) -> None:
        """The node's tasks at :data:`TASK_TABLE`'s periods and priorities, then the VC's own
        tasks and its datalog."""
        tasks: dict[str, Callable[[int], None]] = {
            "commands": self._task_commands,
            "plant": self._task_plant,
            "sfa": self._task_sfa,
            "etcs": self._task_etcs,
            "control": self._task_control,
            "vital_link": self._task_vital_link,
            "session": self._task_session,
            "status": self._task_status,
            "track_data": self.track_data.ask,
        }
        for name, spec in TASK_TABLE.items():
            if name != "vital_link" or vital is not None:
                self.executive.add_task(
                    name, tasks[name], period_s=spec.period_s, priority=spec.priority
                )
        if vital is not None:
            self._datalog = _register_vital_control(vital, self.executive, self.settings.vc_datalog)

    @property
    def sc_state(self) -> m.ScState:
        return self.stack.driving.state

    @property
    def target_speed_mps(self) -> float | None:
        return self.stack.remote_target_mps if self.stack.remote_selected else None

    # -- Zenoh side (called on Zenoh's threads) ------------------------------------------------

    def _on_trackside_liveliness(self, _key: str, alive: bool) -> None:
        if not alive:
            self.barrier.disarm()

    # -- tasks (called by the executive) -------------------------------------------------------

    def _task_commands(self, now_ns: int) -> None:
        self.track_data.step(now_ns)
        self.intake.take(now_ns)
        self._emit_all(self.commands.execute_queued(now_ns / NS_PER_S), now_ns)
        self._emit_all(self.stack.take_events(), now_ns)

    def _task_plant(self, now_ns: int) -> None:
        """The VCU (bogie model) turns the force demand into actuator commands on the last
        tick's readings; the vehicle moves, and its sensors sample."""
        now_s, dt_s = now_ns / NS_PER_S, TASK_TABLE["plant"].period_s
        plant, demand = self.plant, self.stack.force_demand_n
        if self.vcu is not None:
            wheels, powertrain = plant.wheels, plant.powertrain_reading()
            assert wheels is not None
            assert powertrain is not None
            self.stack.energy.read(powertrain)
            commands = self.vcu.step(
                dt_s,
                demand,
                fused_speed_mps=self.sensor_fusion.speed_mps,
                wheels=wheels,
                powertrain=powertrain,
            )
            plant.step(now_s, dt_s, commands, emergency_brake=self.stack.emergency_brake(now_s))
            return
        plant.step(now_s, dt_s, demand, emergency_brake=self.stack.emergency_brake(now_s))

    def _task_sfa(self, now_ns: int) -> None:
        now_s = now_ns / NS_PER_S
        self.sensor_fusion.step(now_s, self.plant.take_datagrams())
        for marker in self.plant.take_marker_detections():
            self.sensor_fusion.fix(
                marker.marker.position_m, marker.time_s, sigma_m=MARKER_FIX_SIGMA_M
            )
        if self.stack.vital is not None:
            self.stack.vital.fused_speed(self.sensor_fusion.speed_mps, now_s)

    def _task_vital_link(self, now_ns: int) -> None:
        self.stack.step_vital_link(now_ns / NS_PER_S)

    def _task_etcs(self, now_ns: int) -> None:
        plant = self.plant
        self.stack.step_etcs(
            now_ns / NS_PER_S, plant.take_wheel_readings(), plant.take_balise_detections()
        )

    def _task_control(self, now_ns: int) -> None:
        inputs = ControlInputs(
            applied_force_n=self.plant.drive.applied_force_n,
            session_alive=self.session_client.established,
            internal_fault=self.internal_fault,
        )
        self.stack.step_control(now_ns / NS_PER_S, inputs)

    def _task_session(self, now_ns: int) -> None:
        """Handshake when due, take acknowledgements and terminations, check the timeouts."""
        self.session_link.step(now_ns, track_data_version=self.track_database.onboard_version)

    @property
    def trackside_seen(self) -> bool:
        """Whether a trackside's liveliness token is seen now."""
        return self.ports.trackside_seen

    def _task_status(self, now_ns: int) -> None:
        client = self.session_client
        # Lockstep: the previous report's acknowledgement is taken at this tick, one status
        # period after the report, however fast it came back (it had that long to come).
        if self.barrier.take(self._resend_status):
            self._task_session(now_ns)
        if not client.status_due(now_ns / NS_PER_S, self._status_seq):
            return
        self.barrier.sending()
        self._last_report = self.status(now_ns)
        self.ports.publish_status(self._last_report)
        self._status_seq += 1
        self.barrier.sent(in_session=client.established)

    def _resend_status(self) -> bool:
        """The last report once more (same ``seq``: the trackside counts a duplicate as
        stale); whether there was one."""
        if self._last_report is None:
            return False
        self.ports.publish_status(self._last_report)
        return True

    @property
    def inputs_received(self) -> tuple[int, int, int]:
        """Journey profiles, movement authorities and TSRs received so far (lockstep drivers wait on
        these so that a message sent between two slices is taken at the next one)."""
        return self.ports.inputs_received

    @property
    def status_ack_outstanding(self) -> bool:
        """Lockstep: the last report sent in the session still waits for its acknowledgement (a
        driver that cuts the link waits for it first, so the cut falls at a tick fixed by
        simulated time, not by when the acknowledgement happened to travel)."""
        return self.barrier.outstanding

    @property
    def barrier_misses(self) -> int:
        """Lockstep status barriers that ended without the acknowledgement (a run with none
        is independent of the machine's speed)."""
        return self.barrier.misses

    @property
    def report_retransmissions(self) -> int:
        return self.barrier.retransmissions

    @property
    def commands_rejected(self) -> int:
        """Commands refused on arrival."""
        return self.commands.rejected

    @property
    def reports_sent(self) -> int:
        """Status reports published so far (the next report's ``seq``)."""
        return self._status_seq

    # -- state ---------------------------------------------------------------------------------

    def current_status(self) -> m.StatusReport:
        """The status now: the report sent at this tick, if one was, else a new one."""
        report, now_ns = self._last_report, self.clock.now_ns
        if report is not None and abs(report.sim_time_s - now_ns / NS_PER_S) < 1e-9:
            return report
        return self.status(now_ns)

    def status(self, now_ns: int) -> m.StatusReport:
        return status_report(
            self.stack,
            vehicle_id=self.vehicle_id,
            seq=self._status_seq,
            now_s=now_ns / NS_PER_S,
            acceleration_mps2=self.sensor_fusion.acceleration_mps2,
            traction_force_n=self.plant.drive.applied_force_n,
            target_speed_mps=self.target_speed_mps,
            track_data_pending=self.track_data.pending_version,
        )

    def emit(
        self, severity: m.EventSeverity, code: str, text: str, *, now_ns: int | None = None
    ) -> None:
        at_ns = self.clock.now_ns if now_ns is None else now_ns
        self.ports.emit(severity, code, text, at_s=at_ns / NS_PER_S)

    def _emit_at(self, severity: m.EventSeverity, code: str, text: str, now_ns: int) -> None:
        self.emit(severity, code, text, now_ns=now_ns)

    def _emit_all(self, events: Iterable[StackEvent], now_ns: int) -> None:
        for event in events:
            self.emit(event.severity, event.code, event.text, now_ns=now_ns)

    # -- life cycle ----------------------------------------------------------------------------

    def run(self, duration_s: float | None = None) -> None:
        """Run the tasks for ``duration_s`` of simulated time, or until :meth:`stop`."""
        if duration_s is None:
            self.executive.run_until(None)
        else:
            self.executive.run_for(duration_s)

    def stop(self) -> None:
        self.executive.stop()

    def close(self) -> None:
        """Withdraw from the network: the token goes first, so trackside sees it at once."""
        self.ports.withdraw()
        termination = self.session_client.terminate("onboard closing", self.clock.now_s)
        if termination is not None:
            self.ports.terminate(termination)
        self.ports.close()
        if self._datalog is not None:
            self._datalog.close()


def _wheel_travel_m(plant: SimulatedVehicle) -> tuple[float, float]:
    """The (front, rear) axles' travel [m] as the axle-end sensors last read it."""
    wheels = plant.wheels
    return (0.0, 0.0) if wheels is None else (wheels.travel_front_m, wheels.travel_rear_m)


def _vital_control(
    settings: OnboardSettings,
    wheel_travel_m: Callable[[], tuple[float, float]],
    *,
    start_s: float,
) -> VcInstallation | None:
    """The Vital Control the settings fit (None: none), on the axles' travel readings."""
    if not settings.vital_control:
        return None
    return VcInstallation(
        wheel_travel_m,
        config=settings.vc_config,
        replicas=settings.vc_replicas,
        faults=settings.vc_faults,
        start_s=start_s,
    )


def _register_vital_control(
    vital: VcInstallation, executive: Executive, datalog_path: Path | None
) -> Datalog | None:
    """The VC's own tasks on the executive, and its datalog recorder if a path is given."""
    vital.register(executive)
    if datalog_path is None:
        return None
    datalog = Datalog(datalog_path)
    DatalogRecorder(datalog, vital.boards[0].vc, pair=vital.pair).register(
        executive, period_s=vital.config.task_a_period_s
    )
    return datalog


def _energy_data(settings: OnboardSettings) -> tuple[VcuParameters, PowertrainParameters]:
    """The VCU's and the powertrain's data of the settings' vehicle: the URV's, with the range
    extender's rated power if the settings give one (its working points scaled to it)."""
    vcu, powertrain = vcu_parameters_for(URV_BOGIE_PARAMETERS), PowertrainParameters()
    power_w = settings.range_extender_power_w
    if power_w is None:
        return vcu, powertrain
    extender = powertrain.range_extender
    scale = power_w / extender.working_points_w[-1]
    points = tuple(point * scale for point in extender.working_points_w)
    return (
        dataclasses.replace(vcu, range_extender_max_power_w=power_w),
        dataclasses.replace(
            powertrain, range_extender=dataclasses.replace(extender, working_points_w=points)
        ),
    )


def _simulated_vehicle(
    settings: OnboardSettings,
    track_map: TrackMap,
    powertrain: PowertrainParameters,
    *,
    start_s: float,
) -> SimulatedVehicle:
    """The dynamics at the settings' fidelity, with the sensors that watch them (their
    randomness from the sensors' seed, one stream each)."""
    sensors, position_m = settings.sensors, settings.start_position_m
    wheel_rng = np.random.default_rng([sensors.seed, 2])
    # One wheel-diameter error for every sensor that reads the wheels (the axle-end sensors and
    # the sensor fusion's wheel-based odometer), so that they agree.
    diameter_error = sensors.wheel_diameter_error
    if diameter_error is None:
        diameter_error = draw_diameter_error(wheel_rng)
    dynamics = (
        BogiePlant(
            URV_BOGIE_PARAMETERS,
            position_m=position_m,
            initial_soc=settings.initial_soc,
            powertrain=powertrain,
        )
        if settings.fidelity == "bogie"
        else PointMassModel(URV_PARAMETERS, position_m=position_m)
    )
    return SimulatedVehicle(
        track_map,
        dynamics,
        interface_modules=InterfaceModules(
            track_map,
            rng=np.random.default_rng(sensors.seed),
            noise=sensors.noise,
            faults=sensors.faults,
            diameter_error=diameter_error,
        ),
        wheel_sensors=WheelSensors(rng=wheel_rng, diameter_error=diameter_error),
        balise_reader=BaliseReader(
            track_map,
            rng=np.random.default_rng([sensors.seed, 3]),
            faults=BaliseReaderFaults(missed_group_ids=sensors.missed_balise_groups),
        ),
        marker_reader=StopMarkerReader(
            track_map,
            rng=np.random.default_rng([sensors.seed, 4]),
            faults=StopMarkerReaderFaults(missed_marker_ids=sensors.missed_stop_markers),
        ),
        start_s=start_s,
    )
