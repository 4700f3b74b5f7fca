"""The ATO-OB process of one vehicle: its Zenoh seams and its table of tasks.

The node declares the vehicle's liveliness token, answers trackside commands, publishes status at
5 Hz and events as they happen, and runs the plant and the remote-driving controller on the
executive. Commands are validated and acknowledged on arrival, then executed at the next release
of the ``commands`` task, so that what they change happens at a tick of simulated time.

Until the ETCS, localisation and ATO-OB controller issues land, the node reports ETCS in Staff
Responsible (SR: the seed 000 field test starts remote driving in SR), the ATO-OB Not Available
(NA: no journey profile) and reads speed and position from the plant.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from dataclasses import dataclass
from typing import Literal, Protocol

import zenoh

from onboard.adf import RemoteDrivingController
from onboard.plant import URV_PARAMETERS, PointMassModel
from onboard.runtime import Clock, Executive
from onboard.runtime.clock import NS_PER_S
from onboard.track_database_manager import TrackDatabaseManager
from onboard.vcu.vehicle import BogieVehicle
from protocol import (
    ProtocolError,
    TypedPublisher,
    TypedQueryable,
    TypedSubscriber,
    declare_liveliness,
    request_async,
)
from protocol import messages as m
from protocol.registry import (
    ALIVE_ONBOARD,
    COMMAND,
    EVENT,
    JOURNEY_PROFILE,
    JOURNEY_PROFILE_ACK,
    LINE_VERSION,
    STATUS,
)
from trackdb import TrackMap

__all__ = ["Fidelity", "OnboardNode", "OnboardSettings", "Plant", "TASK_TABLE"]

_log = logging.getLogger(__name__)


Fidelity = Literal["point_mass", "bogie"]


class Plant(Protocol):
    """What the node needs of a plant; both fidelities provide it."""

    @property
    def position_m(self) -> float: ...

    @property
    def speed_mps(self) -> float: ...

    @property
    def acceleration_mps2(self) -> float: ...

    @property
    def applied_force_n(self) -> float: ...

    def force_limits_n(self, speed_mps: float) -> tuple[float, float]: ...

    def step(
        self, dt_s: float, force_demand_n: float, *, gradient_permille: float = ...,
        curve_radius_m: float = ...,
    ) -> None: ...  # fmt: skip


@dataclass(frozen=True)
class TaskSpec:
    period_s: float
    priority: int


TASK_TABLE: dict[str, TaskSpec] = {
    "commands": TaskSpec(period_s=0.05, priority=40),
    "plant": TaskSpec(period_s=0.01, priority=30),
    "rd_control": TaskSpec(period_s=0.1, priority=20),
    "status": TaskSpec(period_s=0.2, priority=10),
    "track_data": TaskSpec(period_s=5.0, priority=5),
}
"""The onboard tasks: period [s] and priority (higher runs first at a shared release)."""


@dataclass(frozen=True, kw_only=True)
class OnboardSettings:
    vehicle_id: str
    line_id: str = "bologna-ring"
    start_position_m: float = 0.0
    fidelity: Fidelity = "point_mass"
    """The plant: the point-mass model, or the 10-DOF bogie model behind the VCU."""


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
        self.track_database = TrackDatabaseManager(track_map)
        self._session = session
        self.clock = clock
        self.executive = Executive(clock)
        self.plant: Plant = (
            BogieVehicle(position_m=settings.start_position_m)
            if settings.fidelity == "bogie"
            else PointMassModel(URV_PARAMETERS, position_m=settings.start_position_m)
        )
        self.rd_controller = RemoteDrivingController(
            mass_kg=URV_PARAMETERS.mass_kg,
            rolling_coefficient=URV_PARAMETERS.davis_a_n / (URV_PARAMETERS.mass_kg * 9.81),
        )
        self.sc_state = m.ScState.OFF
        self.target_speed_mps: float | None = None
        self._force_demand_n = 0.0
        self._inbox: deque[m.Command] = deque()
        self._inbox_lock = threading.Lock()
        self._status_seq = 0
        self._event_seq = 0
        self.commands_rejected = 0

        chunks = {"vehicle": self.vehicle_id}
        self._status = TypedPublisher(session, STATUS, **chunks)
        self._events = TypedPublisher(session, EVENT, **chunks)
        self._commands = TypedQueryable(session, COMMAND, self._on_command, **chunks)
        self._journeys = TypedSubscriber(session, JOURNEY_PROFILE, vehicle=self.vehicle_id)
        self._journey_acks = TypedPublisher(session, JOURNEY_PROFILE_ACK, **chunks)
        self._line_version: m.LineVersionReply | None = None
        self._token = declare_liveliness(session, ALIVE_ONBOARD.format(vehicle=self.vehicle_id))

        for name, spec in TASK_TABLE.items():
            self.executive.add_task(
                name, getattr(self, f"_task_{name}"), period_s=spec.period_s,
                priority=spec.priority,
            )  # fmt: skip
        self.emit(m.EventSeverity.INFO, "onboard.started", f"line {track_map.line.id}")

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
        body = command.body
        if isinstance(body, m.EngageCommand):
            return "ATO-OB not available: no journey profile accepted"
        if isinstance(body, m.DisengageCommand):
            return "ATO-OB is not engaged"
        if isinstance(body, m.RemoteDrivingTargetCommand):
            limit = self.track_map.speed_limit_mps(self.plant.position_m)
            if body.target_speed_mps > limit:
                return f"target {body.target_speed_mps:.2f} m/s above line speed {limit:.2f} m/s"
        return None

    # -- tasks (called by the executive) -------------------------------------------------------

    def _on_line_version(self, reply: m.LineVersionReply) -> None:
        with self._inbox_lock:
            self._line_version = reply

    def _task_track_data(self, now_ns: int) -> None:
        """Ask the trackside which version of the line it holds (answered asynchronously)."""
        request = m.LineVersionRequest(vehicle_id=self.vehicle_id, line_id=self.track_map.line.id)
        try:
            request_async(
                self._session, LINE_VERSION, request, self._on_line_version,
                line=self.track_map.line.id,
            )  # fmt: skip
        except ProtocolError as exc:
            self.emit(m.EventSeverity.WARNING, "track_data.query_failed", str(exc), now_ns=now_ns)

    def _take_line_version(self, now_ns: int) -> None:
        with self._inbox_lock:
            reply, self._line_version = self._line_version, None
        if reply is None:
            return
        matched_before = self.track_database.versions_match
        self.track_database.record_trackside_version(reply)
        if self.track_database.versions_match != matched_before or reply.version is None:
            code = "track_data.match" if self.track_database.versions_match else "track_data.differ"
            severity = (
                m.EventSeverity.INFO if code == "track_data.match" else m.EventSeverity.WARNING
            )
            onboard = self.track_database.onboard_version
            text = f"trackside {reply.version or 'unknown'} onboard {onboard}"
            self.emit(severity, code, text, now_ns=now_ns)

    def _take_journeys(self, now_ns: int) -> None:
        while (received := self._journeys.try_recv()) is not None:
            _, profile = received
            if profile.vehicle_id != self.vehicle_id:
                review_reason: str | None = f"journey for {profile.vehicle_id}"
                accepted = False
            else:
                review = self.track_database.review(profile)
                accepted, review_reason = review.accepted, review.reason
            self._journey_acks.put(
                m.JourneyProfileAck(
                    vehicle_id=self.vehicle_id, journey_id=profile.journey_id,
                    version=profile.version, accepted=accepted, reason=review_reason,
                )
            )  # fmt: skip
            verdict = "accepted" if accepted else f"refused: {review_reason}"
            self.emit(
                m.EventSeverity.INFO if accepted else m.EventSeverity.WARNING,
                "journey.accepted" if accepted else "journey.refused",
                f"journey {profile.journey_id} v{profile.version} {verdict}", now_ns=now_ns,
            )  # fmt: skip

    def _task_commands(self, now_ns: int) -> None:
        self._take_line_version(now_ns)
        self._take_journeys(now_ns)
        while True:
            with self._inbox_lock:
                if not self._inbox:
                    return
                command = self._inbox.popleft()
            body = command.body
            if isinstance(body, m.RemoteDrivingTargetCommand):
                if self.sc_state is m.ScState.OFF:
                    self.rd_controller.reset(self.plant.speed_mps)
                    self.sc_state = m.ScState.RD
                self.target_speed_mps = body.target_speed_mps
                self.emit(
                    m.EventSeverity.INFO, "rd.target_speed",
                    f"target {body.target_speed_mps * 3.6:.1f} km/h by {command.issued_by}",
                    now_ns=now_ns,
                )  # fmt: skip

    def _task_plant(self, _now_ns: int) -> None:
        position = self.plant.position_m
        self.plant.step(
            TASK_TABLE["plant"].period_s,
            self._force_demand_n,
            gradient_permille=self.track_map.gradient_permille(position),
            curve_radius_m=self.track_map.curve_radius_m(position),
        )

    def _task_rd_control(self, _now_ns: int) -> None:
        if self.sc_state is not m.ScState.RD or self.target_speed_mps is None:
            self._force_demand_n = self.plant.force_limits_n(self.plant.speed_mps)[0]
            return
        position = self.plant.position_m
        target = min(self.target_speed_mps, self.track_map.speed_limit_mps(position))
        self._force_demand_n = self.rd_controller.step(
            TASK_TABLE["rd_control"].period_s,
            target_speed_mps=target,
            speed_mps=self.plant.speed_mps,
            gradient_permille=self.track_map.gradient_permille(position),
            force_limits_n=self.plant.force_limits_n(self.plant.speed_mps),
        )

    def _task_status(self, now_ns: int) -> None:
        self._status.put(self.status(now_ns))
        self._status_seq += 1

    @property
    def reports_sent(self) -> int:
        """Status reports published so far (the next report's ``seq``)."""
        return self._status_seq

    # -- state ---------------------------------------------------------------------------------

    def status(self, now_ns: int) -> m.StatusReport:
        return m.StatusReport(
            vehicle_id=self.vehicle_id,
            seq=self._status_seq,
            sim_time_s=now_ns / NS_PER_S,
            line_id=self.track_map.line.id,
            position_m=self.track_map.normalise(self.plant.position_m),
            speed_mps=self.plant.speed_mps,
            acceleration_mps2=self.plant.acceleration_mps2,
            traction_force_n=self.plant.applied_force_n,
            ato_state=m.AtoState.NOT_AVAILABLE,
            etcs_mode=m.EtcsMode.SR,
            sc_state=self.sc_state,
            target_speed_mps=self.target_speed_mps,
            journey_id=None
            if self.track_database.journey is None
            else self.track_database.journey.journey_id,
        )

    def emit(
        self, severity: m.EventSeverity, code: str, text: str, *, now_ns: int | None = None
    ) -> None:
        at_ns = self.clock.now_ns if now_ns is None else now_ns
        self._events.put(
            m.Event(
                vehicle_id=self.vehicle_id, seq=self._event_seq, sim_time_s=at_ns / NS_PER_S,
                severity=severity, code=code, text=text,
            )
        )  # fmt: skip
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
        self._commands.close()
        self._journeys.close()
        self._journey_acks.close()
        self._status.close()
        self._events.close()
