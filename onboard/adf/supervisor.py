"""The supervisory controller (SC) of the ADF, seed 000 §5: who drives, and bumpless hand-over.

States: OFF (no ADF control; the vehicle is held), RD (remote driving: the PID follows the
operator's target), AD (autonomous driving: the NMPC follows the ODP), and the two hand-over
states HRD2AD and HAD2RD in which both controllers run and the applied force moves linearly from
the outgoing controller's output to the incoming one's over ``handover_s``. A reverse request
during a hand-over turns it round from where the blend stands, so the force never jumps.
A request for OFF is obeyed at once (disengagement, emergency). Every change of the driving mode
asks for a replan of the ODP from the current reference (:attr:`replan_requested`).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from protocol.messages import ScState

__all__ = ["ModeRequest", "ScTransition", "SupervisoryController"]

DEFAULT_HANDOVER_S = 2.0


class ModeRequest(StrEnum):
    """What the ATO-OB controller asks of the ADF."""

    OFF = "off"
    REMOTE = "remote"
    AUTONOMOUS = "autonomous"


@dataclass(frozen=True)
class ScTransition:
    at_s: float
    source: ScState
    target: ScState


class SupervisoryController:
    """The SC state machine and its blend of the two controllers' outputs."""

    def __init__(self, *, handover_s: float = DEFAULT_HANDOVER_S) -> None:
        if handover_s <= 0:
            raise ValueError("the hand-over needs a positive duration")
        self.handover_s = handover_s
        self.state = ScState.OFF
        self.transitions: list[ScTransition] = []
        self.replan_requested = False
        self._blend = 0.0
        """Share of AD in the applied force during a hand-over, 0..1."""

    @property
    def needs_remote(self) -> bool:
        """Whether the RD controller must run this cycle."""
        return self.state in (ScState.RD, ScState.HRD2AD, ScState.HAD2RD)

    @property
    def needs_autonomous(self) -> bool:
        """Whether the AD controller must run this cycle."""
        return self.state in (ScState.AD, ScState.HRD2AD, ScState.HAD2RD)

    def request(self, mode: ModeRequest, now_s: float) -> None:
        """Take a mode request from the ATO-OB controller."""
        target = {
            (ModeRequest.OFF, ScState.OFF): None,
            (ModeRequest.REMOTE, ScState.OFF): ScState.RD,
            (ModeRequest.REMOTE, ScState.AD): ScState.HAD2RD,
            (ModeRequest.REMOTE, ScState.HRD2AD): ScState.HAD2RD,
            (ModeRequest.AUTONOMOUS, ScState.OFF): ScState.AD,
            (ModeRequest.AUTONOMOUS, ScState.RD): ScState.HRD2AD,
            (ModeRequest.AUTONOMOUS, ScState.HAD2RD): ScState.HRD2AD,
        }.get((mode, self.state))
        if mode is ModeRequest.OFF and self.state is not ScState.OFF:
            target = ScState.OFF
        if target is None:
            return
        if target is ScState.OFF:
            self._blend = 0.0
        elif target is ScState.AD:
            self._blend = 1.0
        elif target is ScState.RD:
            self._blend = 0.0
        self._enter(target, now_s)

    def _enter(self, target: ScState, now_s: float) -> None:
        self.transitions.append(ScTransition(now_s, self.state, target))
        self.state = target
        self.replan_requested = True

    def acknowledge_replan(self) -> None:
        """The ODP has been replanned from the current reference."""
        self.replan_requested = False

    def output(self, *, remote_force_n: float, autonomous_force_n: float) -> float | None:
        """The force the SC applies now for these controller outputs, without advancing."""
        if self.state is ScState.OFF:
            return None
        return (1.0 - self._blend) * remote_force_n + self._blend * autonomous_force_n

    def step(
        self, dt_s: float, now_s: float, *, remote_force_n: float, autonomous_force_n: float
    ) -> float | None:
        """The force to apply [N], or ``None`` when the SC is OFF (the vehicle is held).

        Both forces are read only in the states that need them; pass 0 for the others.
        """
        if self.state is ScState.OFF:
            return None
        if self.state is ScState.HRD2AD:
            self._blend = min(1.0, self._blend + dt_s / self.handover_s)
            if self._blend >= 1.0:
                self._enter(ScState.AD, now_s)
        elif self.state is ScState.HAD2RD:
            self._blend = max(0.0, self._blend - dt_s / self.handover_s)
            if self._blend <= 0.0:
                self._enter(ScState.RD, now_s)
        return self.output(remote_force_n=remote_force_n, autonomous_force_n=autonomous_force_n)
