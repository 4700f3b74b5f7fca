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

import logging
import math
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import zenoh

from onboard.etcs import EtcsError
from onboard.plant import URV_PARAMETERS, PointMassModel
from onboard.plant.balise_reader import BaliseReader, BaliseReaderFaults
from onboard.plant.bogie_parameters import URV_BOGIE_PARAMETERS
from onboard.plant.sensors import InterfaceModules
from onboard.plant.vehicle import BogiePlant, SimulatedVehicle
from onboard.plant.wheel_sensors import WheelSensors, draw_diameter_error
from onboard.runtime import Clock, Executive, SimClock
from onboard.runtime.clock import NS_PER_S
from onboard.session import SessionClient
from onboard.sfa.chain import SensorFusionChain, SensorSettings
from onboard.stack import OnboardStack
from onboard.vc import Datalog, DatalogRecorder, VcConfig
from onboard.vc.installation import VcFaults, VcInstallation
from onboard.vcu import vcu_parameters_for
from onboard.vcu.drive import VcuDrive
from protocol import (
    LivelinessWatcher,
    ProtocolError,
    RequestTimeoutError,
    TypedPublisher,
    TypedQueryable,
    TypedSubscriber,
    declare_liveliness,
    request,
    request_async,
)
from protocol import messages as m
from protocol.registry import (
    ALIVE_ONBOARD,
    ALIVE_TRACKSIDE,
    COMMAND,
    EVENT,
    JOURNEY_PROFILE,
    JOURNEY_PROFILE_ACK,
    LINE_VERSION,
    MOVEMENT_AUTHORITY,
    SESSION,
    SESSION_TERMINATION,
    SPEED_RESTRICTION,
    STATUS,
    STATUS_ACK,
)
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap

__all__ = ["Fidelity", "NODE_VC_CONFIG", "OnboardNode", "OnboardSettings", "TASK_TABLE"]

_log = logging.getLogger(__name__)

Fidelity = Literal["point_mass", "bogie"]
BARRIER_S = 10.0
"""Lockstep: the longest wall time a status report waits for its acknowledgement. Long, so that a
loaded machine never changes a run; the wait ends at once when the trackside's liveliness token
goes, and is not made again until a session is established anew."""
RETRANSMIT_S = 2.0
"""Lockstep: after this long without an acknowledgement [s of wall time] the report is sent
once more (a report lost on the way would otherwise cost the session)."""
HANDSHAKE_RETRY_S = 0.02
"""Lockstep: wall time between two tries of a handshake a seen trackside has not answered [s]."""


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


class OnboardNode:
    """One vehicle's onboard process, bound to an open Zenoh session and a clock."""

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
        self._session = session
        self.clock = clock
        self.lockstep = isinstance(clock, SimClock)
        self.executive = Executive(clock)
        self.plant = _simulated_vehicle(settings, track_map, start_s=clock.now_s)
        self.vcu = (
            VcuDrive(vcu_parameters_for(URV_BOGIE_PARAMETERS))
            if settings.fidelity == "bogie"
            else None
        )
        vital = (
            VcInstallation(
                self._wheel_travel_m,
                config=settings.vc_config,
                replicas=settings.vc_replicas,
                faults=settings.vc_faults,
                start_s=clock.now_s,
            )
            if settings.vital_control
            else None
        )
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
        )
        self._datalog: Datalog | None = None
        self.track_database = self.stack.track_database
        self.session_client = SessionClient(
            vehicle_id=self.vehicle_id,
            etcs_id=settings.etcs_id,
            train_length_m=settings.train_length_m,
        )
        self._inbox: deque[m.Command] = deque()
        self._inbox_lock = threading.Lock()
        self._session_replies: deque[m.SessionAccept | m.SessionReject | None] = deque()
        self._status_seq = 0
        self._event_seq = 0
        self.commands_rejected = 0

        chunks = {"vehicle": self.vehicle_id}
        # In lockstep each report in a session waits for its acknowledgement: it must not be
        # dropped under congestion, as a latest-value topic otherwise is.
        self._status = TypedPublisher(session, STATUS, block=self.lockstep, vehicle=self.vehicle_id)
        self._last_report: m.StatusReport | None = None
        self.report_retransmissions = 0
        self._events = TypedPublisher(session, EVENT, vehicle=self.vehicle_id)
        self._commands = TypedQueryable(session, COMMAND, self._on_command, **chunks)
        self._journeys = TypedSubscriber(session, JOURNEY_PROFILE, vehicle=self.vehicle_id)
        self._journey_acks = TypedPublisher(session, JOURNEY_PROFILE_ACK, vehicle=self.vehicle_id)
        self._status_acked = threading.Event()
        self._ack_pending = False
        # One subscriber queues the acknowledgement and then wakes the lockstep barrier, so the
        # barrier never wakes before the acknowledgement can be taken. With two subscribers (one
        # to queue, one to wake), Zenoh ran their callbacks apart: the barrier could wake, the
        # session task find nothing, and the report go unacknowledged past the trackside's
        # response timeout (the session was lost in a fault-free lockstep run).
        self._status_acks = TypedSubscriber(
            session,
            STATUS_ACK,
            on_message=lambda _k, _a: self._status_acked.set(),
            vehicle=self.vehicle_id,
        )
        self._terminations = TypedSubscriber(session, SESSION_TERMINATION, vehicle=self.vehicle_id)
        self._termination_out = TypedPublisher(
            session, SESSION_TERMINATION, vehicle=self.vehicle_id
        )
        self._authorities = TypedSubscriber(session, MOVEMENT_AUTHORITY, vehicle=self.vehicle_id)
        self._restrictions = TypedSubscriber(session, SPEED_RESTRICTION, vehicle=self.vehicle_id)
        self._line_version: m.LineVersionReply | None = None
        self.barrier_misses = 0
        """Lockstep status barriers that ended without the acknowledgement (a run with none
        is independent of the machine's speed)."""
        self._barrier_armed = True
        self._tracksides = LivelinessWatcher(
            session, ALIVE_TRACKSIDE.format(instance="*"), self._on_trackside_liveliness
        )
        self._token = declare_liveliness(session, ALIVE_ONBOARD.format(vehicle=self.vehicle_id))

        for name, spec in TASK_TABLE.items():
            if name == "vital_link" and vital is None:
                continue
            self.executive.add_task(
                name,
                getattr(self, f"_task_{name}"),
                period_s=spec.period_s,
                priority=spec.priority,
            )
        if vital is not None:
            vital.register(self.executive)
            if settings.vc_datalog is not None:
                self._datalog = Datalog(settings.vc_datalog)
                DatalogRecorder(self._datalog, vital.boards[0].vc, pair=vital.pair).register(
                    self.executive, period_s=vital.config.task_a_period_s
                )
        self.emit(m.EventSeverity.INFO, "onboard.started", f"line {track_map.line.id}")

    @property
    def sc_state(self) -> m.ScState:
        return self.stack.driving.state

    @property
    def target_speed_mps(self) -> float | None:
        return self.stack.remote_target_mps if self.stack.remote_selected else None

    # -- Zenoh side (called on Zenoh's threads) ------------------------------------------------

    def _on_command(self, _chunks: dict[str, str], command: m.Command) -> m.CommandAck:
        reason = self._refusal(command)
        if reason is None and not isinstance(command.body, m.PingCommand):
            with self._inbox_lock:
                self._inbox.append(command)
        if reason is not None:
            self.commands_rejected += 1
        return m.CommandAck(
            vehicle_id=self.vehicle_id,
            command_id=command.command_id,
            accepted=reason is None,
            reason=reason,
            sim_time_s=self.clock.now_s,
        )

    def _refusal(self, command: m.Command) -> str | None:
        if command.vehicle_id != self.vehicle_id:
            return f"command for {command.vehicle_id} reached {self.vehicle_id}"
        return self.stack.refusal(command.body)

    def _on_line_version(self, reply: m.LineVersionReply) -> None:
        with self._inbox_lock:
            self._line_version = reply

    def _on_trackside_liveliness(self, _key: str, alive: bool) -> None:
        if not alive:
            # A trackside went away: no acknowledgement will come, so the barrier ends now and
            # is not waited on again before the next handshake.
            self._barrier_armed = False
            self._status_acked.set()

    def _on_session_reply(self, reply: m.SessionAccept | m.SessionReject) -> None:
        with self._inbox_lock:
            self._session_replies.append(reply)

    # -- tasks (called by the executive) -------------------------------------------------------

    def _task_track_data(self, now_ns: int) -> None:
        """Ask the trackside which version of the line it holds (answered asynchronously)."""
        request = m.LineVersionRequest(vehicle_id=self.vehicle_id, line_id=self.track_map.line.id)
        try:
            request_async(
                self._session,
                LINE_VERSION,
                request,
                self._on_line_version,
                line=self.track_map.line.id,
            )
        except ProtocolError as exc:
            self.emit(m.EventSeverity.WARNING, "track_data.query_failed", str(exc), now_ns=now_ns)

    def _take_line_version(self, now_ns: int) -> None:
        with self._inbox_lock:
            reply, self._line_version = self._line_version, None
        if reply is None:
            return
        database = self.track_database
        matched_before = database.versions_match
        database.record_trackside_version(reply)
        if database.versions_match != matched_before or reply.version is None:
            code = "track_data.match" if database.versions_match else "track_data.differ"
            severity = m.EventSeverity.INFO if database.versions_match else m.EventSeverity.WARNING
            text = f"trackside {reply.version or 'unknown'} onboard {database.onboard_version}"
            self.emit(severity, code, text, now_ns=now_ns)

    def _take_journeys(self, now_ns: int) -> None:
        now_s = now_ns / NS_PER_S
        while (received := self._journeys.try_recv()) is not None:
            _, profile = received
            if not self.session_client.on_journey_profile(profile, now_s):
                self.emit(
                    m.EventSeverity.WARNING,
                    "journey.stale",
                    f"journey {profile.journey_id} v{profile.version} dropped",
                    now_ns=now_ns,
                )
                continue
            accepted, reason = self.stack.review_journey(profile)
            self._journey_acks.put(
                m.JourneyProfileAck(
                    vehicle_id=self.vehicle_id,
                    journey_id=profile.journey_id,
                    version=profile.version,
                    accepted=accepted,
                    reason=reason,
                )
            )
            verdict = "accepted" if accepted else f"refused: {reason}"
            self.emit(
                m.EventSeverity.INFO if accepted else m.EventSeverity.WARNING,
                "journey.accepted" if accepted else "journey.refused",
                f"journey {profile.journey_id} v{profile.version} {verdict}",
                now_ns=now_ns,
            )

    def _take_authorities(self, now_ns: int) -> None:
        while (received := self._authorities.try_recv()) is not None:
            _, message = received
            if message.vehicle_id != self.vehicle_id:
                continue
            try:
                what = self.stack.receive_movement_authority(message, now_ns / NS_PER_S)
            except EtcsError as exc:
                self.emit(m.EventSeverity.WARNING, "etcs.ma_refused", str(exc), now_ns=now_ns)
                continue
            self.emit(m.EventSeverity.INFO, "etcs.ma", f"MA {message.ma_id} {what}", now_ns=now_ns)

    def _take_speed_restrictions(self, now_ns: int) -> None:
        while (received := self._restrictions.try_recv()) is not None:
            _, message = received
            if message.vehicle_id != self.vehicle_id:
                continue
            try:
                what = self.stack.receive_speed_restriction(message, now_ns / NS_PER_S)
            except ValueError as exc:
                self.emit(m.EventSeverity.WARNING, "etcs.tsr_refused", str(exc), now_ns=now_ns)
                continue
            self.emit(m.EventSeverity.INFO, "etcs.tsr", what, now_ns=now_ns)

    def _task_commands(self, now_ns: int) -> None:
        now_s = now_ns / NS_PER_S
        self._take_line_version(now_ns)
        self._take_journeys(now_ns)
        self._take_authorities(now_ns)
        self._take_speed_restrictions(now_ns)
        while True:
            with self._inbox_lock:
                if not self._inbox:
                    break
                command = self._inbox.popleft()
            self._execute(command, now_s, now_ns)
        for event in self.stack.events:
            self.emit(event.severity, event.code, event.text, now_ns=now_ns)
        self.stack.events.clear()

    def _execute(self, command: m.Command, now_s: float, now_ns: int) -> None:
        body = command.body
        refused: str | None = None
        if isinstance(body, m.RemoteDrivingTargetCommand):
            refused = self.stack.refusal(body)
            if refused is None:
                self.stack.remote(body.target_speed_mps, now_s)
                self.emit(
                    m.EventSeverity.INFO,
                    "rd.target_speed",
                    f"target {body.target_speed_mps / MPS_PER_KMH:.1f} km/h by {command.issued_by}",
                    now_ns=now_ns,
                )
        elif isinstance(body, m.EngageCommand):
            refused = self.stack.engage(now_s)
            if refused is None:
                self.emit(
                    m.EventSeverity.INFO, "ato.engaged", f"by {command.issued_by}", now_ns=now_ns
                )
        elif isinstance(body, m.DisengageCommand):
            refused = self.stack.disengage(now_s)
            if refused is None:
                self.emit(
                    m.EventSeverity.INFO, "ato.disengaged", f"by {command.issued_by}", now_ns=now_ns
                )
        elif isinstance(body, m.SkipStopCommand):
            refused = self.stack.refusal(body)
            if refused is None:
                self.stack.skip_stop(body.timing_point_id, now_s)
                self.emit(
                    m.EventSeverity.INFO,
                    "journey.skip_stop",
                    f"{body.timing_point_id} skipped by {command.issued_by}",
                    now_ns=now_ns,
                )
        elif isinstance(body, m.TrainHoldCommand):
            refused = self.stack.refusal(body)
            if refused is None:
                self.stack.train_hold(body.hold, now_s)
                self.emit(
                    m.EventSeverity.INFO,
                    "journey.train_hold",
                    f"{'held' if body.hold else 'released'} by {command.issued_by}",
                    now_ns=now_ns,
                )
        elif isinstance(body, m.EmergencyBrakeCommand):
            refused = self.stack.operator_emergency_brake()
            if refused is None:
                self.emit(
                    m.EventSeverity.WARNING,
                    "operator.emergency_brake",
                    f"by {command.issued_by}",
                    now_ns=now_ns,
                )
        elif isinstance(body, m.OperatorConfirmCommand):
            refused = self.stack.operator_confirm(body.request, body.number)
            if refused is None:
                self.emit(
                    m.EventSeverity.INFO,
                    f"operator.confirm.{body.request.value}",
                    f"request {body.number} by {command.issued_by}",
                    now_ns=now_ns,
                )
        if refused is not None:
            self.emit(
                m.EventSeverity.WARNING,
                "command.refused",
                f"command {command.command_id}: {refused}",
                now_ns=now_ns,
            )

    def _wheel_travel_m(self) -> tuple[float, float]:
        """The (front, rear) axles' travel [m] as the axle-end sensors last read it."""
        wheels = self.plant.wheels
        return (0.0, 0.0) if wheels is None else (wheels.travel_front_m, wheels.travel_rear_m)

    def _task_plant(self, now_ns: int) -> None:
        """The VCU (bogie model) turns the force demand into actuator commands on the last
        tick's readings; the vehicle moves, and its sensors sample."""
        now_s, dt_s = now_ns / NS_PER_S, TASK_TABLE["plant"].period_s
        plant, demand = self.plant, self.stack.force_demand_n
        if self.vcu is not None:
            wheels, powertrain = plant.wheels, plant.powertrain_reading()
            assert wheels is not None
            assert powertrain is not None
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
        self.stack.session_alive = self.session_client.established
        self.stack.step_control(now_ns / NS_PER_S, self.plant.drive.applied_force_n)

    def _task_session(self, now_ns: int) -> None:
        """Handshake when due, take acknowledgements and terminations, check the timeouts."""
        now_s = now_ns / NS_PER_S
        client = self.session_client
        while (ack := self._status_acks.try_recv()) is not None:
            client.on_status_ack(ack[1].vehicle_id, ack[1].seq, now_s)
        while (received := self._terminations.try_recv()) is not None:
            if client.on_termination(received[1], now_s):
                self.emit(
                    m.EventSeverity.WARNING, "session.terminated", received[1].reason, now_ns=now_ns
                )
        with self._inbox_lock:
            replies = list(self._session_replies)
            self._session_replies.clear()
        for reply in replies:
            self._take_session_reply(reply, now_ns)
        if client.step(now_s):
            text = f"no acknowledgement within {client.response_timeout_s} s"
            self.emit(m.EventSeverity.WARNING, "session.lost", text, now_ns=now_ns)
        handshake = client.request(now_s, track_data_version=self.track_database.onboard_version)
        if handshake is None:
            return
        if self.lockstep:
            self._take_session_reply(self._lockstep_handshake(handshake), now_ns)
            return
        try:
            request_async(
                self._session, SESSION, handshake, self._on_session_reply, vehicle=self.vehicle_id
            )
        except ProtocolError:
            self._take_session_reply(None, now_ns)

    def _lockstep_handshake(
        self, handshake: m.SessionRequest
    ) -> m.SessionAccept | m.SessionReject | None:
        """Lockstep: the handshake's answer, taken at the tick it was asked at. While a trackside's
        token is seen, the request is repeated (up to :data:`BARRIER_S` of wall time) until it is
        answered: the trackside's queryable may reach this session a moment after its token, and a
        loaded machine may answer late, neither of which may change the run. With no trackside
        seen, one try."""
        deadline = time.monotonic() + BARRIER_S
        while True:
            try:
                reply: m.SessionAccept | m.SessionReject = request(
                    self._session, SESSION, handshake, timeout_s=1.0, vehicle=self.vehicle_id
                )
                return reply
            except RequestTimeoutError:
                if not self.trackside_seen or time.monotonic() > deadline:
                    return None
                time.sleep(HANDSHAKE_RETRY_S)
            except ProtocolError:
                return None

    @property
    def trackside_seen(self) -> bool:
        """Whether a trackside's liveliness token is seen now."""
        return bool(self._tracksides.alive())

    def _take_session_reply(
        self, reply: m.SessionAccept | m.SessionReject | None, now_ns: int
    ) -> None:
        client = self.session_client
        client.on_response(reply, now_ns / NS_PER_S)
        if client.established:
            self._barrier_armed = True
            self.emit(
                m.EventSeverity.INFO,
                "session.established",
                f"with {client.trackside_id}",
                now_ns=now_ns,
            )
        elif isinstance(reply, m.SessionReject):
            self.emit(
                m.EventSeverity.WARNING, "session.rejected", reply.reason.value, now_ns=now_ns
            )

    def _task_status(self, now_ns: int) -> None:
        client = self.session_client
        if self._ack_pending:
            # Lockstep: the previous report's acknowledgement is taken at this tick, one status
            # period after the report, however fast it came back (it had that long to come).
            self._ack_pending = False
            # Disarmed (the trackside's token went), no barrier is waited on: none is missed.
            if self._barrier_armed:
                if self._await_status_ack():
                    self._task_session(now_ns)
                if not self._status_acked.is_set():
                    self.barrier_misses += 1
        if not client.status_due(now_ns / NS_PER_S, self._status_seq):
            return
        self._status_acked.clear()
        self._last_report = self.status(now_ns)
        self._status.put(self._last_report)
        self._status_seq += 1
        self._ack_pending = self.lockstep and client.established

    def _await_status_ack(self) -> bool:
        """Lockstep barrier: wait for the last report's acknowledgement; if none came within
        :data:`RETRANSMIT_S`, send the report once more (same ``seq``: the trackside counts a
        duplicate as stale) and wait the rest of :data:`BARRIER_S`."""
        if self._status_acked.wait(RETRANSMIT_S):
            return True
        if not self._barrier_armed or self._last_report is None:
            return False
        self._status.put(self._last_report)
        self.report_retransmissions += 1
        return self._status_acked.wait(BARRIER_S - RETRANSMIT_S)

    @property
    def inputs_received(self) -> tuple[int, int, int]:
        """Journey profiles, movement authorities and TSRs received so far (lockstep drivers wait on
        these so that a message sent between two slices is taken at the next one)."""
        return (
            self._journeys.stats.received,
            self._authorities.stats.received,
            self._restrictions.stats.received,
        )

    @property
    def status_ack_outstanding(self) -> bool:
        """Lockstep: the last report sent in the session still waits for its acknowledgement (a
        driver that cuts the link waits for it first, so the cut falls at a tick fixed by
        simulated time, not by when the acknowledgement happened to travel)."""
        return self._ack_pending and not self._status_acked.is_set()

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
        etcs = self.stack.etcs.output
        journey = self.track_database.journey
        driving, now_s = self.stack.driving, now_ns / NS_PER_S
        position_m, speed_mps = self.stack.position_m, self.stack.speed_mps
        next_stop = driving.next_stop(position_m) if driving.journey else None
        intervention = self.stack.etcs.intervention_speed_mps()
        return m.StatusReport(
            vehicle_id=self.vehicle_id,
            seq=self._status_seq,
            sim_time_s=now_ns / NS_PER_S,
            line_id=self.track_map.line.id,
            position_m=self.track_map.normalise(position_m),
            speed_mps=speed_mps,
            acceleration_mps2=self.sensor_fusion.acceleration_mps2,
            traction_force_n=self.plant.drive.applied_force_n,
            ato_state=self.stack.ato_state,
            etcs_mode=self.stack.etcs.mode,
            sc_state=self.sc_state,
            supervision_status=etcs.supervision_status,
            target_speed_mps=self.target_speed_mps,
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
            vital_control=self.stack.vital_status(),
            permitted_speed_mps=max(etcs.permitted_speed_mps, 0.0),
            intervention_speed_mps=intervention if math.isfinite(intervention) else None,
            reference_speed_mps=driving.reference_speed_mps(now_s),
            train_hold=driving.hold,
        )

    def emit(
        self, severity: m.EventSeverity, code: str, text: str, *, now_ns: int | None = None
    ) -> None:
        at_ns = self.clock.now_ns if now_ns is None else now_ns
        self._events.put(
            m.Event(
                vehicle_id=self.vehicle_id,
                seq=self._event_seq,
                sim_time_s=at_ns / NS_PER_S,
                severity=severity,
                code=code,
                text=text,
            )
        )
        self._event_seq += 1

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
        self._token.undeclare()
        termination = self.session_client.terminate("onboard closing", self.clock.now_s)
        if termination is not None:
            self._termination_out.put(termination)
        self._commands.close()
        for closable in (
            self._journeys,
            self._journey_acks,
            self._status_acks,
            self._terminations,
            self._termination_out,
            self._authorities,
            self._restrictions,
            self._status,
            self._events,
            self._tracksides,
        ):
            closable.close()
        if self._datalog is not None:
            self._datalog.close()


def _simulated_vehicle(
    settings: OnboardSettings, track_map: TrackMap, *, start_s: float
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
        BogiePlant(URV_BOGIE_PARAMETERS, position_m=position_m, initial_soc=settings.initial_soc)
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
        start_s=start_s,
    )
