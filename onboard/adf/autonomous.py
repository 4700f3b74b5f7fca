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
import numpy.typing as npt

from onboard.adf.nmpc import NmpcController, NmpcReference, NmpcResult
from onboard.adf.odp import (
    MAX_ACCELERATION_MPS2,
    SPEED_OVERREAD_SHARE,
    SPEED_UNDERREAD_SHARE,
    OdpPlan,
)
from onboard.adf.odp_energy import LIMIT_BRAKING_MPS2
from onboard.plant.point_mass import CURVE_COEFFICIENT_M, PointMassParameters
from protocol.units import GRAVITY_MPS2, MPS_PER_KMH

__all__ = ["AutonomousDriving"]

STANDSTILL_MPS = 0.05
CEILING_WINDOW_M = np.array([-5.0, 0.0, 5.0])
LEAD_M = 2.0
"""The most the position reference leads the train by at the horizon's start [m]; beyond, by
what the train can run from its speed under the ceilings, accelerating at
:data:`CATCH_UP_MPS2`. A plan the train cannot follow (held back by a permitted speed that rose
later than planned, a weak brake, a fallback law) would otherwise leave a lead the NMPC cannot
close, and its NLP, dominated by that error, does not converge (the ADF re-times a plan the
train has fallen far behind)."""
CATCH_UP_MPS2 = MAX_ACCELERATION_MPS2
"""The plans' highest acceleration: a train keeping up with its plan is never held back."""
REFERENCE_PASSES = 4
"""Passes of the position reference and the ceilings at most (one or two suffice but where
the plan and the train lie on either side of a limit's change)."""
CATCH_UP_BRAKING_MPS2 = LIMIT_BRAKING_MPS2
"""The braking [m/s²] into a lower ceiling later in the horizon that the position reference's
catch-up allows for, as the plans brake into a lower limit: a catch-up at each stage's own
ceiling ran at a higher one up to the stage before a drop and asked to be past it at once."""
ESTIMATE_MARGIN_MPS = 0.1 * MPS_PER_KMH
"""Each ceiling is held this much lower as well [m/s]: the fused speed's error beyond the
odometer's calibration (a train catching up its reference runs on the ceiling)."""
CEILING_MARGIN_MPS = 0.1 * MPS_PER_KMH
"""The speed reference is held this far under each stage's ceiling [m/s] (with the estimate's
margin, where the plans hold it: 0.2 km/h under the limit less the under-read share): a
reference on (or above) a ceiling makes the NLP degenerate."""
COAST_LOOKAHEAD_STEPS = 10
"""The stages ahead (2 s) over which the reference must coast for the train to coast."""
COAST_FORCE_N = 50.0
"""A reference whose own force (its acceleration, the resistance at its speed and the track's
force, on the onboard's model) stays within this [N] coasts."""
COAST_ENTRY_BAND = (1.0, 0.1)
"""Position [m] and speed [m/s] errors against the plan within which the train coasts with it,
under the gentle law of :data:`COAST_GAINS` rather than the NMPC."""
COAST_EXIT_BAND = (3.0, 0.3)
"""... and beyond which the NMPC takes over again (hysteresis)."""
COAST_GAINS = (0.005, 0.1)
"""The acceleration asked per m of position error [1/s²] and per m/s of speed error [1/s]
while coasting with the plan: a closed loop of 20 s, damped 0.7, which leaves the estimate's
noise (σ 0.008 m/s, correlated over 1–2 s) at about 15 N."""
STANDING_MARGIN_N = 300.0
"""Before its departure, a standing train's demand is held this far [N] under what would move
it on the onboard's model (the resistance at rest and the track's force): the brake is released
and the traction built up ahead of the reference, which then leaves with the train rather than
0.6–1 s ahead of it, and the model's error (Davis ±10 %, mass +5 % on a 30 ‰ descent: about
250 N) still leaves the train standing."""
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
        self._step_s = config.step_s
        self.last_result: NmpcResult | None = None
        self.coasting = False
        """Whether the train coasts with the plan (the NMPC left out)."""
        self.permitted_speed_mps = math.inf
        """The ETCS permitted speed [m/s], a ceiling over the whole horizon."""
        self._sampled: tuple[float, list[float], list[float]] | None = None
        self._samples: dict[float, tuple[float, float]] = {}
        """The plan's reference at the last horizon's stages, by instant [s]."""
        self._final_braking_mps2: float | None = None
        """The plan's deceleration into the stop the reference comes to rest at [m/s²]."""

    def set_permitted_speed(self, permitted_speed_mps: float) -> None:
        """The ETCS permitted speed the ATO-OB controller passes on: a ceiling over the horizon.
        The EoA is the plan's business: the ADF replans to stop before it."""
        self.permitted_speed_mps = permitted_speed_mps

    def reference(
        self, now_s: float, *, speed_mps: float | None = None, distance_m: float | None = None
    ) -> NmpcReference:
        """The horizon's reference at ``now_s``. With the measured ``speed_mps``, the permitted
        speed is not set below what full braking can reach from that speed (a ceiling the
        vehicle cannot meet would make the NLP infeasible; ETCS supervises beyond). With the
        measured ``distance_m``, the positions lead it by at most :data:`LEAD_M` plus what the
        ceilings let the train run."""
        positions, speeds = self._horizon(now_s)
        planned = np.array(positions)
        targets, ceilings = planned, self._ceilings(planned, speed_mps)
        if distance_m is not None and speed_mps is not None:
            # The ceilings where the train is to be, as well as where the plan is, and positions
            # it can run under those very ceilings: until neither moves (each pass lowers both).
            for _ in range(REFERENCE_PASSES):
                runnable = self._runnable_mps(ceilings, speed_mps)
                lead = distance_m + LEAD_M + np.cumsum(runnable) * self._step_s
                targets = np.minimum(planned, lead)
                lower = np.minimum(ceilings, self._ceilings(targets, speed_mps))
                if np.array_equal(lower, ceilings):
                    break
                ceilings = lower
        speeds_mps = np.minimum(np.array(speeds), np.maximum(ceilings - CEILING_MARGIN_MPS, 0.0))
        forces = [self._track_force_n(self.plan.chainage_m(float(d))) for d in targets]
        return NmpcReference(targets, speeds_mps, ceilings, np.array(forces))

    def _runnable_mps(
        self, ceilings: npt.NDArray[np.float64], speed_mps: float
    ) -> npt.NDArray[np.float64]:
        """The speeds [m/s] a train catching up runs at the horizon's stages: held under each
        stage's ceiling as the speed reference is, braking at :data:`CATCH_UP_BRAKING_MPS2`
        into every lower ceiling later in the horizon (at stage k, at most v_j + b (t_j − t_k)
        for every j ≥ k), and accelerating at :data:`CATCH_UP_MPS2` from ``speed_mps`` and from
        every lower speed earlier in it (at most v_j + a (t_k − t_j) for every j ≤ k)."""
        held = np.maximum(ceilings - CEILING_MARGIN_MPS, 0.0)
        braking = CATCH_UP_BRAKING_MPS2 * self._offsets_s
        into = np.minimum.accumulate((held + braking)[::-1])[::-1] - braking
        rising = CATCH_UP_MPS2 * self._offsets_s
        runnable: npt.NDArray[np.float64] = np.minimum(
            np.minimum.accumulate(into - rising) + rising, max(speed_mps, 0.0) + rising
        )
        return runnable

    def _horizon(self, now_s: float) -> tuple[list[float], list[float]]:
        """The plan's distances and speeds at the horizon's stages from ``now_s``, sampled once
        a step for the reference and the final approach's cap."""
        if self._sampled is None or self._sampled[0] != now_s:
            # The next step's stages are mostly this step's, one stage on: the samples at the
            # very same instants (float for float) are taken again, not recomputed.
            reference, previous = self.plan.reference, self._samples
            times: list[float] = (now_s + self._offsets_s).tolist()
            samples = {t: previous.get(t) or reference(t) for t in times}
            self._samples = samples
            values = samples.values()
            self._sampled = (now_s, [d for d, _ in values], [v for _, v in values])
        return self._sampled[1], self._sampled[2]

    def _ceilings(
        self, positions: npt.NDArray[np.float64], speed_mps: float | None
    ) -> npt.NDArray[np.float64]:
        """Each stage's ceiling [m/s]: the lowest MRSP within a few metres of its position (the
        train may run a little ahead of it) and the journey's cap less the measured speed's
        under-read share, and the permitted speed less that share too, or less ETCS's own
        over-read share where it lies under them; with the measured ``speed_mps``, never below
        what full braking reaches from it."""
        around = np.add.outer(positions, CEILING_WINDOW_M)
        origin = self.plan.start_chainage_m
        mrsp: npt.NDArray[np.float64] = self.plan.track_map.mrsp_ahead_mps(origin, around)
        limits: npt.NDArray[np.float64] = mrsp.min(axis=1)
        if self.plan.cap_mps is not None:
            limits = np.minimum(limits, self.plan.cap_mps)
        # On the measured speed, which may read low by the odometer's tolerance. Under the
        # limits, the permitted speed is a braking curve's down to a target's speed, which ETCS
        # supervises on its own speed, without CSM's margins: near the target it intervenes at
        # any reading above it, and its windowed speed reads up to a pulse (0.26 km/h) high
        # (docs/decisions.md, "Issue 18"). It is held by ETCS's over-read share there.
        permitted = self.permitted_speed_mps
        share = np.where(permitted < limits, SPEED_OVERREAD_SHARE, SPEED_UNDERREAD_SHARE)
        ceilings = np.minimum(limits * (1.0 - SPEED_UNDERREAD_SHARE), permitted * (1.0 - share))
        ceilings = ceilings - ESTIMATE_MARGIN_MPS
        if speed_mps is not None:
            # A ceiling the vehicle is already above (a permitted speed that drops at once, an
            # overshoot) it can meet only after braking: held at what full braking reaches.
            delay = np.maximum(self._offsets_s - REACHABLE_DELAY_S, 0.0)
            reachable = np.maximum(speed_mps - REACHABLE_BRAKING_MPS2 * delay, 0.0)
            ceilings = np.maximum(ceilings, reachable)
        return ceilings

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
        at_rest_now = target_speed == 0.0 and speed_mps < STANDSTILL_MPS
        at_rest = at_rest_now and self.plan.reference(now_s + 1.0)[1] == 0.0
        if at_rest and abs(distance_m - target_distance) < 1.0:
            self.controller.reset()
            return -self.model.max_brake_force_n
        if speed_mps < STANDSTILL_MPS:
            # A brake holding a stopped vehicle exerts only a reaction, which the model (made
            # for motion) would read as a force pushing it backwards.
            applied_force_n = max(applied_force_n, 0.0)
        reference = self.reference(now_s, speed_mps=speed_mps, distance_m=distance_m)
        errors = (target_distance - distance_m, target_speed - speed_mps)
        if self._coasts(reference, errors):
            # The NMPC starts again from the force applied when it takes over.
            self.controller.reset()
            mass = self.model.mass_kg * (1.0 + self.model.rotating_mass_factor)
            demand = mass * (COAST_GAINS[0] * errors[0] + COAST_GAINS[1] * errors[1])
            return min(demand, self.stopping_force_n(now_s, distance_m, speed_mps))
        result = self.controller.solve(
            position_m=distance_m,
            speed_mps=speed_mps,
            applied_force_n=applied_force_n,
            reference=reference,
        )
        self.last_result = result
        if at_rest_now and abs(distance_m - target_distance) < 1.0:
            # Prepared for the departure, not yet gone: the NMPC's next rate bound starts from
            # the demand sent.
            demand = min(result.force_n, self._standing_force_n(distance_m))
            self.controller.note_demand(demand)
            return demand
        return min(result.force_n, self.stopping_force_n(now_s, distance_m, speed_mps))

    def _standing_force_n(self, distance_m: float) -> float:
        """The most a train standing before its departure is asked for [N]: the force that would
        move it on the onboard's model, less :data:`STANDING_MARGIN_N`."""
        track = self._track_force_n(self.plan.chainage_m(distance_m))
        return self.model.davis_a_n + track - STANDING_MARGIN_N

    def _coasts(self, reference: NmpcReference, errors: tuple[float, float]) -> bool:
        """Whether the train coasts now: the plan coasts over the next
        :data:`COAST_LOOKAHEAD_STEPS` and the train keeps within a band of it.

        Where the plan coasts the NMPC, which tracks it to centimetres, answered the truth's
        small departures from the onboard's model and the estimate's noise with ±100–300 N,
        alternately traction and brake: 0.056 kWh of the 0.76 of bologna-ring's journey, where
        the plan takes none. Coasting with the plan within a band, the train runs on the true
        train's own coasting; the NMPC corrects only what leaves the band."""
        band = COAST_EXIT_BAND if self.coasting else COAST_ENTRY_BAND
        self.coasting = (
            abs(errors[0]) <= band[0]
            and abs(errors[1]) <= band[1]
            and _reference_coasts(reference, self.model, self._step_s)
        )
        return self.coasting

    def stopping_force_n(self, now_s: float, distance_m: float, speed_mps: float) -> float:
        """A ceiling on the demand in the final approach [N]: where the reference comes to rest
        within the horizon, d ahead, and the train is faster than the plan's braking curve into
        that stop (v²/2d above the plan's final deceleration), the force of the constant
        deceleration v²/2d, which stops it there; +inf otherwise.

        The NMPC's model, made for motion, would roll back under a brake held to standstill, so
        it eases the brake off a few seconds early, and the train, which the real brake stops
        and holds, ran about 0.2·a s² past its stop: 0.06–0.14 m at the plans' 0.35–0.7 m/s²."""
        positions, speeds = self._horizon(now_s)
        if speeds[-1] > 0.0:
            self._final_braking_mps2 = None
            return math.inf
        # The first stage at rest: a replanned profile may end a hair below zero, not at it.
        rest = next(k for k, speed in enumerate(speeds) if speed <= 0.0)
        if rest >= 2:  # the reference's deceleration just before it comes to rest
            self._final_braking_mps2 = (speeds[rest - 2] - speeds[rest - 1]) / self._step_s
        braking = self._final_braking_mps2
        if braking is None or speed_mps < STANDSTILL_MPS:
            return math.inf
        remaining_m = positions[-1] - distance_m
        if remaining_m <= 0.0:
            return -self.model.max_brake_force_n
        needed_mps2 = speed_mps * speed_mps / (2.0 * remaining_m)
        if needed_mps2 <= braking:
            return math.inf
        m = self.model
        mass = m.mass_kg * (1.0 + m.rotating_mass_factor)
        resistance = (
            m.davis_a_n + m.davis_b_n_per_mps * speed_mps + m.davis_c_n_per_mps2 * speed_mps**2
        )
        track = self._track_force_n(self.plan.chainage_m(distance_m))
        return min(resistance + track - mass * needed_mps2, 0.0)


def _reference_coasts(reference: NmpcReference, model: PointMassParameters, step_s: float) -> bool:
    """Whether the reference's own force stays within :data:`COAST_FORCE_N` over the next
    :data:`COAST_LOOKAHEAD_STEPS` stages, the train moving."""
    speeds = reference.speed_mps[: COAST_LOOKAHEAD_STEPS + 1]
    if speeds.min() <= STANDSTILL_MPS:
        return False
    mass = model.mass_kg * (1.0 + model.rotating_mass_factor)
    v = speeds[:-1]
    forces = (
        mass * np.diff(speeds) / step_s
        + model.davis_a_n
        + model.davis_b_n_per_mps * v
        + model.davis_c_n_per_mps2 * v * v
        + reference.track_force_n[:COAST_LOOKAHEAD_STEPS]
    )
    return bool(np.abs(forces).max() <= COAST_FORCE_N)
