"""VcInstallation: the Vital Control as fitted to a vehicle, with its emulated I/O.

The VC library (:class:`~onboard.vc.module.VitalControl`, :class:`~onboard.vc.redundancy.
TwoOutOfTwo`) sees the world through ports; on a vehicle those ports are wired to:

- the **odometry board**: a :class:`~onboard.vc.hardware.TachometerBoard` counting the
  pulses of the axle-end sensors, channel A on the front axle and channel B on the rear one
  (wheel rotation: slip and slide show; the VC's own speed and position; with
  ``VcConfig.fused_speed_supervision`` Task B also takes the fused speed, every 10 ms, through
  :meth:`VcInstallation.fused_speed`);
- the **BTM**: the header of each balise telegram the ETCS reads, forwarded to Task B;
- the **EB valves and brake pipe**: the pipe's venting is the share of the full EB force the
  plant applies (:meth:`VcInstallation.emergency_brake`);
- the **radio relay** in the ETCS-OB's power supply: its contact (as re-read) isolates or
  inserts the emulated ETCS onboard (:meth:`VcInstallation.etcs_isolated`).

One board, or two replicas in 2-out-of-2 (``replicas=2``): each replica has its own link to the
ATO-OB, its own relay and its own output contact; the vehicle's valves are the pair's, and ETCS
is isolated when either relay has cut its power. The I/O task ``vc.io`` runs before the VC's
Task B at every tick it shares with it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from onboard.etcs.balises import TelegramHeader
from onboard.runtime import Executive
from onboard.runtime.clock import NS_PER_S
from onboard.vc.config import VcConfig
from onboard.vc.hardware import (
    EmergencyBrakeValves,
    PipeFault,
    RelayFault,
    TachometerBoard,
    TachometerFault,
)
from onboard.vc.ipc import Delivery
from onboard.vc.link import FaultyLink, LinkFault
from onboard.vc.messages import AtoObResponse, VcRequest
from onboard.vc.module import TASK_B_PRIORITY, VcHardware, VcOutputs, VitalControl
from onboard.vc.redundancy import RedundancyConfig, ReplicaFault, TwoOutOfTwo

__all__ = ["IO_PRIORITY", "VcFaults", "VcInstallation"]

IO_PRIORITY = TASK_B_PRIORITY + 10
"""The I/O task runs before Task B in a shared tick, so B sees this tick's frames."""
IO_PERIOD_S = 0.010
"""The odometry board's 80 ms and the plant's 10 ms are multiples of this period [s]."""


@dataclass(frozen=True, kw_only=True)
class VcFaults:
    """Faults injected into the VC's surroundings (scenario runs, tests)."""

    link: Sequence[LinkFault] = ()
    tachometer: Sequence[TachometerFault] = ()
    relay: Sequence[RelayFault] = ()
    pipe: Sequence[PipeFault] = ()
    replicas: Sequence[ReplicaFault] = ()


@dataclass
class _Board:
    """One VC board: the library and its ports."""

    hardware: VcHardware
    vc: VitalControl
    tachometer: TachometerBoard


class VcInstallation:
    """The vehicle's Vital Control: one board or two in 2-out-of-2, with emulated I/O.

    Parameters
    ----------
    wheel_travel_m
        The (front, rear) axles' travel [m] as the axle-end sensors read it (wheel rotation
        times the calibrated radius), read at each I/O cycle.
    config
        The VC's parameters (both replicas use the same).
    replicas
        1, or 2 for 2-out-of-2.
    faults
        Injected faults.
    start_s
        Power-up time [s]: the valves are de-energised (fail-safe) until the first rearm.
    """

    def __init__(
        self,
        wheel_travel_m: Callable[[], tuple[float, float]],
        *,
        config: VcConfig | None = None,
        replicas: int = 1,
        redundancy: RedundancyConfig | None = None,
        faults: VcFaults | None = None,
        start_s: float = 0.0,
    ) -> None:
        if replicas not in (1, 2):
            raise ValueError(f"a VC is one board or a 2-out-of-2 pair, got {replicas}")
        self.config = config or VcConfig()
        self.faults = faults or VcFaults()
        self.start_s = start_s
        self._wheel_travel_m = wheel_travel_m
        self._travel_start_m = wheel_travel_m()
        self.boards = tuple(self._board(index, start_s) for index in range(replicas))
        self.pair: TwoOutOfTwo | None = None
        if replicas == 2:
            self.pair = TwoOutOfTwo(
                (self.boards[0].vc, self.boards[1].vc),
                valves=EmergencyBrakeValves(start_s=start_s, faults=self.faults.pipe),
                config=redundancy,
                faults=self.faults.replicas,
                start_s=start_s,
            )
        self._balises: list[TelegramHeader] = []

    def _board(self, index: int, start_s: float) -> _Board:
        faults = self.faults
        hardware = VcHardware.emulated(
            link_faults=faults.link,
            pipe_faults=faults.pipe,
            relay_faults=faults.relay,
            start_s=start_s,
        )
        tachometer = TachometerBoard(
            metres_per_pulse=self.config.metres_per_pulse,
            period_s=self.config.tachometer_period_s,
            start_s=start_s,
            faults=faults.tachometer,
            seed=index,
        )
        return _Board(
            hardware, VitalControl(hardware, config=self.config, start_s=start_s), tachometer
        )

    # -- wiring --------------------------------------------------------------------------------

    @property
    def links(self) -> tuple[tuple[FaultyLink[VcRequest], FaultyLink[AtoObResponse]], ...]:
        """Each board's (request, response) link, for the ATO-OB's ends."""
        return tuple((b.hardware.request_link, b.hardware.response_link) for b in self.boards)

    @property
    def valves(self) -> EmergencyBrakeValves:
        """The valves that brake the vehicle: the board's, or the pair's."""
        return self.pair.valves if self.pair is not None else self.boards[0].hardware.valves

    def register(
        self, executive: Executive, *, phase_s: float = 0.0, event_driven: bool | None = None
    ) -> None:
        """Add ``vc.io`` and the VC's tasks (and the pair's voter) to ``executive``;
        ``event_driven``: Tasks B and C skip their quiet cycles (None: in lockstep only)."""
        executive.add_task(
            "vc.io", self._io, period_s=IO_PERIOD_S, phase_s=phase_s, priority=IO_PRIORITY
        )
        if self.pair is not None:
            self.pair.register(executive, phase_s=phase_s, event_driven=event_driven)
        else:
            self.boards[0].vc.register(executive, phase_s=phase_s, event_driven=event_driven)

    def balise_read(self, header: TelegramHeader) -> None:
        """The BTM read a telegram with this header; forwarded at the next I/O cycle."""
        self._balises.append(header)

    def fused_speed(self, speed_mps: float, now_s: float) -> None:
        """The sensor-fusion speed, for ``VcConfig.fused_speed_supervision`` (ignored without
        it): delivered to each board's Task B at once, as over the VC's input bus."""
        if not self.config.fused_speed_supervision:
            return
        for board in self.boards:
            board.hardware.fused_speeds.put(Delivery(speed_mps, now_s))

    def _io(self, release_ns: int) -> None:
        now_s = release_ns / NS_PER_S
        front_m, rear_m = self._wheel_travel_m()
        start_front_m, start_rear_m = self._travel_start_m
        for board in self.boards:
            frame = board.tachometer.poll(now_s, front_m - start_front_m, rear_m - start_rear_m)
            if frame is not None:
                board.hardware.tachometer_frames.put(Delivery(frame, now_s))
            for header in self._balises:
                board.hardware.balise_telegrams.put(Delivery(header, now_s))
        self._balises.clear()

    # -- outputs -------------------------------------------------------------------------------

    def emergency_brake(self, now_s: float) -> float:
        """The EB's share of the full brake force now, 0 to 1, as the pipe vents."""
        return self.valves.brake_effort(now_s)

    def etcs_isolated(self, now_s: float) -> bool:
        """ETCS's power is cut by a relay contact (as it stands now, not as commanded)."""
        return any(not b.hardware.relay.inserted(now_s) for b in self.boards)

    @property
    def outputs(self) -> VcOutputs:
        """The first board's outputs (in 2-out-of-2 the voter keeps both alike)."""
        return self.boards[0].vc.outputs

    @property
    def eb_commanded(self) -> bool:
        return not self.valves.energised

    @property
    def tripped(self) -> bool:
        return self.pair is not None and self.pair.tripped
