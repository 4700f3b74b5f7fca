"""Autonomous driving (AD): the NMPC following the ODP along the line.

Builds the NMPC's per-stage reference from the plan: p_ref and v_ref at each step of the horizon;
the speed ceiling v_max from the MRSP around the reference position (never above it) and the
journey's cap (a hard constraint, as the MRSP: the plan holds a small margin under both, which
is the NMPC's room to catch up), lowered to the ETCS permitted speed when the ATO-OB sets it
(the EoA is the plan's: the ADF replans to stop before it); and the track forces (gradient and
curve) at the reference position, as the seed's control-oriented model takes them. At
standstill at a stop, with the reference at rest, the brake holds the vehicle.
"""

from __future__ import annotations

import math

import numpy as np

from onboard.adf.nmpc import NmpcController, NmpcReference, NmpcResult
from onboard.adf.odp import OdpPlan
from onboard.plant.point_mass import CURVE_COEFFICIENT_M, PointMassParameters
from protocol.units import GRAVITY_MPS2

__all__ = ["AutonomousDriving"]

STANDSTILL_MPS = 0.05
CEILING_WINDOW_M = np.array([-5.0, 0.0, 5.0])
REACHABLE_BRAKING_MPS2 = 0.7
REACHABLE_DELAY_S = 1.2
"""Full braking as the NMPC can reach it: its rate bound and the actuator's lag take about a
second to build the brake up; the URV then brakes at 0.88–0.93 m/s², taken with a margin."""


class AutonomousDriving:
    """Turns the ODP and the measured state into a force demand [N]."""

    def __init__(
        self, plan: OdpPlan, model: PointMassParameters, controller: NmpcController
    ) -> None:
        self.plan = plan
        self.model = model
        self.controller = controller
        config = controller.config
        self._offsets_s = np.arange(1, config.horizon_steps + 1) * config.step_s
        self.last_result: NmpcResult | None = None
        self.permitted_speed_mps = math.inf
        """The ETCS permitted speed [m/s], a ceiling over the whole horizon."""

    def set_permitted_speed(self, permitted_speed_mps: float) -> None:
        """The ETCS permitted speed the ATO-OB controller passes on: a ceiling over the horizon.
        The EoA is the plan's business: the ADF replans to stop before it."""
        self.permitted_speed_mps = permitted_speed_mps

    def reference(self, now_s: float, *, speed_mps: float | None = None) -> NmpcReference:
        """The horizon's reference at ``now_s``. With the measured ``speed_mps``, the permitted
        speed is not set below what full braking can reach from that speed (a ceiling the
        vehicle cannot meet would make the NLP infeasible; ETCS supervises beyond)."""
        track_map = self.plan.track_map
        positions, speeds, forces = [], [], []
        for t in now_s + self._offsets_s:
            distance, speed = self.plan.reference(float(t))
            positions.append(distance)
            speeds.append(speed)
            forces.append(self._track_force_n(self.plan.chainage_m(distance)))
        # The ceiling of a stage is the lowest MRSP within a few metres of its reference
        # position: the train may run a little ahead of its reference.
        origin = self.plan.start_chainage_m
        around = np.add.outer(np.array(positions), CEILING_WINDOW_M)
        ceilings = track_map.mrsp_ahead_mps(origin, around).min(axis=1)
        ceilings = np.minimum(ceilings, self.permitted_speed_mps)
        if self.plan.cap_mps is not None:
            ceilings = np.minimum(ceilings, self.plan.cap_mps)
        if speed_mps is not None:
            # A ceiling the vehicle is already above (a permitted speed that drops at once, an
            # overshoot) it can meet only after braking: held at what full braking reaches.
            delay = np.maximum(self._offsets_s - REACHABLE_DELAY_S, 0.0)
            reachable = np.maximum(speed_mps - REACHABLE_BRAKING_MPS2 * delay, 0.0)
            ceilings = np.maximum(ceilings, reachable)
        return NmpcReference(np.array(positions), np.array(speeds), ceilings, np.array(forces))

    def _track_force_n(self, chainage_m: float) -> float:
        track_map = self.plan.track_map
        weight = self.model.mass_kg * GRAVITY_MPS2
        grade = weight * math.sin(math.atan(track_map.gradient_permille(chainage_m) / 1000.0))
        radius = track_map.curve_radius_m(chainage_m)
        curve = 0.0 if math.isinf(radius) else weight * CURVE_COEFFICIENT_M / radius / 1000.0
        return grade + curve

    def force_n(
        self, now_s: float, *, distance_m: float, speed_mps: float, applied_force_n: float
    ) -> float:
        """The force to apply now, from the measured distance travelled and speed."""
        target_distance, target_speed = self.plan.reference(now_s)
        at_rest = target_speed == 0.0 and self.plan.reference(now_s + 1.0)[1] == 0.0
        if at_rest and speed_mps < STANDSTILL_MPS and abs(distance_m - target_distance) < 1.0:
            self.controller.reset()
            return -self.model.max_brake_force_n
        if speed_mps < STANDSTILL_MPS:
            # A brake holding a stopped vehicle exerts only a reaction, which the model (made
            # for motion) would read as a force pushing it backwards.
            applied_force_n = max(applied_force_n, 0.0)
        result = self.controller.solve(
            position_m=distance_m, speed_mps=speed_mps, applied_force_n=applied_force_n,
            reference=self.reference(now_s, speed_mps=speed_mps),
        )  # fmt: skip
        self.last_result = result
        return result.force_n
