"""VitalControl: the three tasks wired by their mailboxes and registered on the executive.

:class:`VitalControl` builds Tasks A, B and C (:mod:`onboard.vc.task_a`, ``task_b``,
``task_c``) around a :class:`VcHardware`, the VC's ports: the two directions of the ATO-OB
link, the EB valves, the ETCS radio relay, the odometry board's and the BTM's queues. It
registers the tasks on an :class:`onboard.runtime.Executive` with the seeds' periods and
priorities (B > C > A, all released together at the same phase, seed 004 Table 5) and exposes
the outputs. The tasks share no mutable state: each reads the others' frozen statuses from
mailboxes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from onboard.etcs.balises import TelegramHeader
from onboard.runtime import Executive, Task
from onboard.runtime.clock import NS_PER_S
from onboard.vc.config import VcConfig
from onboard.vc.fsm import BrakeState, EtcsState, FsmTransition, TaskAState, TaskBState
from onboard.vc.hardware import (
    FULL_EB_DELAY_S,
    RECHARGE_S,
    RELAY_SWITCHING_DELAY_S,
    EmergencyBrakeValves,
    PipeFault,
    RadioRelay,
    RelayFault,
    TachometerFrame,
)
from onboard.vc.ipc import (
    ActuationStatus,
    Delivery,
    Mailbox,
    MessageQueue,
    SupervisionStatus,
    VcEvent,
)
from onboard.vc.link import FaultyLink, LinkDirection, LinkFault, corrupt_response
from onboard.vc.messages import (
    AtoObResponse,
    DecayReason,
    EbCondition,
    Notification,
    VcRequest,
)
from onboard.vc.quiet import skips_quiet_cycles
from onboard.vc.task_a import TaskA
from onboard.vc.task_b import TaskB
from onboard.vc.task_c import TaskC
from onboard.vc.tick import QuietTick

__all__ = [
    "TASK_A_PRIORITY",
    "TASK_B_PRIORITY",
    "TASK_C_PRIORITY",
    "VcHardware",
    "VcOutputs",
    "VitalControl",
]

TASK_B_PRIORITY = 30
TASK_C_PRIORITY = 20
TASK_A_PRIORITY = 10
"""B > C > A (seed 004). Whatever feeds the VC's inputs in a tick must run above B."""


@dataclass(frozen=True, kw_only=True)
class VcHardware:
    """The VC's ports; :meth:`emulated` builds them on :mod:`onboard.vc.hardware`'s emulators."""

    request_link: FaultyLink[VcRequest]
    response_link: FaultyLink[AtoObResponse]
    valves: EmergencyBrakeValves
    relay: RadioRelay
    tachometer_frames: MessageQueue[Delivery[TachometerFrame]] = field(default_factory=MessageQueue)
    balise_telegrams: MessageQueue[Delivery[TelegramHeader]] = field(default_factory=MessageQueue)
    fused_speeds: MessageQueue[Delivery[float]] = field(default_factory=MessageQueue)
    """The sensor-fusion speed [m/s], for ``VcConfig.fused_speed_supervision``."""

    @classmethod
    def emulated(
        cls,
        *,
        link_delay_s: float = 0.001,
        link_faults: Sequence[LinkFault] = (),
        venting_s: float = FULL_EB_DELAY_S,
        recharge_s: float = RECHARGE_S,
        pipe_faults: Sequence[PipeFault] = (),
        etcs_inserted: bool = True,
        relay_switching_delay_s: float = RELAY_SWITCHING_DELAY_S,
        relay_faults: Sequence[RelayFault] = (),
        start_s: float = 0.0,
    ) -> VcHardware:
        """Emulated ports: valves de-energised and pipe vented at power-up."""
        return cls(
            request_link=FaultyLink(
                LinkDirection.REQUEST, delay_s=link_delay_s, faults=link_faults
            ),
            response_link=FaultyLink(
                LinkDirection.RESPONSE,
                delay_s=link_delay_s,
                faults=link_faults,
                corrupt=corrupt_response,
            ),
            valves=EmergencyBrakeValves(
                venting_s=venting_s, recharge_s=recharge_s, start_s=start_s, faults=pipe_faults
            ),
            relay=RadioRelay(
                inserted=etcs_inserted,
                switching_delay_s=relay_switching_delay_s,
                faults=relay_faults,
            ),
        )


@dataclass(frozen=True, kw_only=True)
class VcOutputs:
    """What the VC shows the rest of the onboard after its last cycle."""

    time_s: float
    eb_commanded: bool
    """The valves are de-energised (EB applied or being applied)."""
    system_decay: bool
    decay_reasons: tuple[DecayReason, ...]
    eb_conditions: tuple[EbCondition, ...]
    """The conditions behind the EB flag now raised."""
    etcs_isolated: bool
    """The radio relay as last re-read."""
    notifications: tuple[Notification, ...]
    """Those of the last request sent."""
    task_a_state: TaskAState
    task_b_state: TaskBState
    brake_state: BrakeState
    etcs_state: EtcsState
    speed_mps: float | None
    position_m: float | None
    standstill: bool
    odometry_efficient: bool


class VitalControl:
    """One Vital Control module: Tasks A, B and C over ``hardware``.

    Parameters
    ----------
    hardware
        The ports; the relay's state at construction is taken as the power-up state.
    config
        Periods, windows, timeouts, thresholds.
    start_s
        Power-up time [s].
    """

    def __init__(
        self, hardware: VcHardware, *, config: VcConfig | None = None, start_s: float = 0.0
    ) -> None:
        self.config = config or VcConfig()
        self.hardware = hardware
        self.start_s = start_s
        requests_sent = MessageQueue[VcRequest](capacity=8)
        supervision = Mailbox[SupervisionStatus]()
        actuation = Mailbox[ActuationStatus]()
        self.task_b = TaskB(
            self.config,
            response_link=hardware.response_link,
            requests_sent=requests_sent,
            tachometer_frames=hardware.tachometer_frames,
            balise_telegrams=hardware.balise_telegrams,
            fused_speeds=hardware.fused_speeds,
            read_eb_released=hardware.valves.eb_released,
            read_etcs_inserted=hardware.relay.inserted,
            actuation=actuation,
            status=supervision,
            start_s=start_s,
        )
        self.task_c = TaskC(
            self.config,
            supervision=supervision,
            command_valves=hardware.valves.command,
            command_relay=hardware.relay.command,
            etcs_inserted=hardware.relay.commanded_inserted,
            status=actuation,
        )
        self.tick: QuietTick | None = None
        """Tasks B and C as one sleeping task (lockstep: :mod:`onboard.vc.tick`)."""
        self.task_a = TaskA(
            self.config,
            request_link=hardware.request_link,
            requests_sent=requests_sent,
            supervision=supervision,
            actuation=actuation,
            start_s=start_s,
        )

    def skip_quiet_cycles(self, enabled: bool) -> None:
        """Tasks B and C skip the cycles that cannot change them (:mod:`onboard.vc.quiet`)."""
        self.task_b.quiet.enabled = enabled
        self.task_c.quiet.enabled = enabled

    def register(
        self, executive: Executive, *, phase_s: float = 0.0, event_driven: bool | None = None
    ) -> tuple[Task, ...]:
        """Add the tasks ``vc.B``, ``vc.C`` and ``vc.A`` to ``executive``; returns them.

        ``event_driven``: B and C skip their quiet cycles (None: in lockstep only), released
        as one task ``vc.tick`` that sleeps while they are quiet (:mod:`onboard.vc.tick`)."""
        skip = skips_quiet_cycles(executive, event_driven)
        self.skip_quiet_cycles(skip)
        config = self.config
        if skip and config.task_b_period_s == config.task_c_period_s:
            tick = QuietTick((self,))
            self.tick = tick
            return tick.register(
                executive,
                period_s=config.task_b_period_s,
                phase_s=phase_s,
                priority=TASK_B_PRIORITY,
                task_a=(("vc.A", self._run_a, config.task_a_period_s, TASK_A_PRIORITY),),
            )
        return (
            executive.add_task(
                "vc.B",
                self._run_b,
                period_s=config.task_b_period_s,
                phase_s=phase_s,
                priority=TASK_B_PRIORITY,
            ),
            executive.add_task(
                "vc.C",
                self._run_c,
                period_s=config.task_c_period_s,
                phase_s=phase_s,
                priority=TASK_C_PRIORITY,
            ),
            executive.add_task(
                "vc.A",
                self._run_a,
                period_s=config.task_a_period_s,
                phase_s=phase_s,
                priority=TASK_A_PRIORITY,
            ),
        )

    def _run_b(self, release_ns: int) -> None:
        self.task_b.step(release_ns / NS_PER_S)

    def _run_c(self, release_ns: int) -> None:
        self.task_c.step(release_ns / NS_PER_S)

    def _run_a(self, release_ns: int) -> None:
        self.task_a.step(release_ns / NS_PER_S)

    @property
    def outputs(self) -> VcOutputs:
        b, c = self.task_b.status.read(), self.task_c.status.read()
        request = self.task_a.last_request
        decay_reasons = tuple(
            dict.fromkeys((b.decay_reasons if b else ()) + (c.decay_reasons if c else ()))
        )
        return VcOutputs(
            time_s=max(b.time_s if b else self.start_s, c.time_s if c else self.start_s),
            eb_commanded=not (c.valves_energised if c else False),
            system_decay=bool(decay_reasons) or (c is not None and c.system_decay),
            decay_reasons=decay_reasons,
            eb_conditions=tuple(sorted(b.eb_conditions)) if b else (),
            etcs_isolated=b.etcs_isolated if b else not self.hardware.relay.commanded_inserted,
            notifications=request.notifications if request else (),
            task_a_state=self.task_a.fsm.state,
            task_b_state=self.task_b.fsm.state,
            brake_state=self.task_c.brake.state,
            etcs_state=self.task_c.etcs.state,
            speed_mps=b.speed_mps if b else None,
            position_m=b.position_m if b else None,
            standstill=b.standstill if b else False,
            odometry_efficient=b.odometry_efficient if b else False,
        )

    def vote_key(self) -> tuple[object, ...]:
        """What a 2-out-of-2 pair votes on, as a plain tuple: the fields of
        :class:`~onboard.vc.redundancy.ReplicaView`, in its order, taken as :attr:`outputs`
        takes them but without building them all (the voter asks every 2 ms)."""
        b, c = self.task_b.status.read(), self.task_c.status.read()
        decaying = bool((b.decay_reasons if b else ()) or (c.decay_reasons if c else ()))
        return (
            not (c.valves_energised if c else False),
            decaying or (c is not None and c.system_decay),
            b.etcs_isolated if b else not self.hardware.relay.commanded_inserted,
            self.task_a.fsm.state,
            self.task_b.fsm.state,
            self.task_c.brake.state,
            self.task_c.etcs.state,
            b.standstill if b else False,
            b.odometry_efficient if b else False,
        )

    @property
    def events(self) -> list[VcEvent]:
        """Tasks B's and C's notifications, in time order (B before C within a tick)."""
        return sorted(self.task_b.events + self.task_c.events, key=lambda e: e.time_s)

    @property
    def transitions(self) -> list[FsmTransition]:
        """Every FSM transition taken, in time order."""
        taken = (
            self.task_b.fsm.transitions
            + self.task_c.etcs.transitions
            + self.task_c.brake.transitions
            + self.task_a.fsm.transitions
        )
        return sorted(taken, key=lambda t: t.time_s)
