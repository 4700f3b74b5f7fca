"""The faults of a whole-stack run, put in force as their time or their condition comes.

Windowed faults (an absent operator, a lost Zenoh link, an ATO-OB internal fault, a friction
drop) hold while their window is open, and are re-read at every slice; one-shot faults (an
obstacle, a shortened MA, a trackside restart, a TSR) happen once, at their time or when their
condition first holds. The sensor, UDP and VC faults are not here: they are built into the
vehicle before the run (``deploy.scenario.vehicle_setup``).
"""

from __future__ import annotations

from deploy.scenario.conditions import State
from deploy.scenario.run_context import (
    LINK_WAIT_S,
    RunContext,
    ScenarioRunError,
    forward_m,
    wait_for,
)
from deploy.scenario.schema import (
    AtoFailure,
    Fault,
    FrictionDrop,
    Obstacle,
    ShortenedAuthority,
    TemporarySpeedRestriction,
    TracksideRestart,
    VigilanceAbsent,
    ZenohLinkLoss,
)
from deploy.scenario.trackside_harness import TracksideHarness
from deploy.scenario.zenoh_link import ZenohLinkFault

__all__ = ["OBSTACLE_MARGIN_M", "FaultInjector"]

OBSTACLE_MARGIN_M = 20.0
"""The RBC ends the MA this far before a reported obstacle [m]."""

OneShot = Obstacle | ShortenedAuthority | TracksideRestart | TemporarySpeedRestriction


class FaultInjector:
    """Puts the scenario's faults in force on the node, the link and the trackside."""

    def __init__(
        self, ctx: RunContext, trackside: TracksideHarness, link: ZenohLinkFault | None
    ) -> None:
        self.ctx = ctx
        self.trackside = trackside
        self.link = link
        self._done: set[int] = set()
        """The one-shot faults already injected (by index)."""

    def step(self, now_s: float, state: State) -> None:
        """The faults in force at ``now_s`` [s], with the state's conditions."""
        ctx = self.ctx
        present = ctx.spec.operator.simulated
        internal_fault = False
        adhesion = 1.0
        link_lost: ZenohLinkLoss | None = None
        for index, fault in enumerate(ctx.spec.faults):
            if isinstance(fault, VigilanceAbsent):
                present &= not fault.start_s <= now_s < fault.end_s
            elif isinstance(fault, ZenohLinkLoss):
                if link_lost is None and fault.start_s <= now_s < fault.end_s:
                    link_lost = fault
            elif isinstance(fault, AtoFailure):
                active = fault.start_s <= now_s < fault.end_s
                if active and not ctx.node.internal_fault and not internal_fault:
                    ctx.recorder.hazards_s.append(now_s)
                internal_fault |= active
            elif isinstance(fault, FrictionDrop) and fault.start_s <= now_s < fault.end_s:
                adhesion = min(adhesion, fault.factor)
            elif (
                isinstance(fault, OneShot)
                and index not in self._done
                and fault_due(fault, now_s, state)
            ):
                self._done.add(index)
                self._one_shot(index, fault, now_s)
        self._zenoh_link(link_lost)
        # The operator at the console sees the vehicle only over the link, and answers through it.
        ctx.operator_present = present and link_lost is None
        ctx.node.internal_fault = internal_fault
        ctx.node.plant.adhesion_factor = adhesion

    def _one_shot(self, index: int, fault: OneShot, now_s: float) -> None:
        if isinstance(fault, TemporarySpeedRestriction):
            self.trackside.speed_restriction(f"tsr-{index + 1}", fault)
            return
        self.ctx.recorder.hazards_s.append(now_s)
        self._inject(fault)

    def _zenoh_link(self, lost: ZenohLinkLoss | None) -> None:
        """Cut the onboard ↔ trackside link when a window opens, restore it when none is open;
        the simulation stands still, in wall time, until both sides have seen the change."""
        link, ctx = self.link, self.ctx
        if link is None or link.up == (lost is None):
            return
        if lost is not None:
            # The acknowledgement of the report in flight arrives first, however slow the wire:
            # the loss then starts at this tick in every run.
            if not wait_for(lambda: not ctx.node.status_ack_outstanding):
                raise ScenarioRunError("the status acknowledgement before the cut never came")
            if not link.cut(lost.mode, timeout_s=LINK_WAIT_S):
                raise ScenarioRunError("the sessions did not notice the lost Zenoh link")
            ctx.recorder.hazards_s.append(ctx.now_s)
            ctx.log("link.cut", True, lost.mode)
        else:
            if not link.restore(timeout_s=LINK_WAIT_S):
                raise ScenarioRunError("the Zenoh link did not come back")
            ctx.log("link.restore", True)

    def _inject(self, fault: Fault) -> None:
        ctx = self.ctx
        if isinstance(fault, TracksideRestart):
            held = self.trackside.rbc_state()
            self.trackside.stop()
            # The vehicle sees the trackside go and come back at a tick fixed by simulated time.
            wait_for(lambda: not ctx.node.trackside_seen)
            ctx.run_for(fault.down_s)
            self.trackside.start()
            wait_for(lambda: ctx.node.trackside_seen)
            kept = self.trackside.rbc_state()
            ctx.log("rbc.restored", kept == held, f"before {held}, after {kept}")
            if kept != held:
                ctx.failures.append(f"the RBC lost its state in the restart: {held} -> {kept}")
            return
        node = ctx.node
        here = node.track_map.normalise(node.plant.position_m)
        if isinstance(fault, Obstacle):
            ahead = forward_m(node, here, fault.position_m)
            ctx.recorder.obstacle_m = node.plant.position_m + ahead
            end_m = here + ahead - OBSTACLE_MARGIN_M
            danger_m = 0.0
        else:
            assert isinstance(fault, ShortenedAuthority)
            end_m = here + forward_m(node, here, fault.end_of_authority_m)
            danger_m = fault.danger_point_m
        answer = self.trackside.movement_authority(end_m, absolute=True, danger_point_m=danger_m)
        ctx.log(f"rbc.{fault.kind}", answer.status_code in (200, 201), answer.text[:200])


def fault_due(fault: OneShot, now_s: float, state: State) -> bool:
    """A one-shot fault's time has come and its condition (if any) holds."""
    if fault.at_s is not None and now_s < fault.at_s:
        return False
    condition = getattr(fault, "condition", None)
    return condition is None or bool(condition.holds(state))
