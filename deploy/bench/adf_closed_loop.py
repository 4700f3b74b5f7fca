"""AD in closed loop on the point-mass plant, for tests and benchmarks of the ADF alone.

The controller sees the plant's true distance and speed (ideal sensors, until the localisation
issue), while the plant may carry a model mismatch. Records what the KPIs need: speed error,
overspeed against the MRSP, accelerations, traction energy, arrivals at stops and NMPC times.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from onboard.adf.autonomous import AutonomousDriving
from onboard.adf.nmpc import NmpcConfig, NmpcController, NmpcStats
from onboard.adf.odp import OdpPlan
from onboard.adf.odp_energy import replan_from_state
from onboard.adf.rd_controller import RemoteDrivingController
from onboard.adf.supervisor import ModeRequest, SupervisoryController
from onboard.plant.point_mass import PointMassModel, PointMassParameters
from protocol.units import GRAVITY_MPS2, MPS_PER_KMH
from trackdb import TrackMap

__all__ = [
    "ClosedLoopRecord",
    "HandoverRecord",
    "Stop",
    "run_autonomous_journey",
    "run_handover_sequence",
]

FloatArray = npt.NDArray[np.float64]
STOPPED_MPS = 0.01
STOP_SEARCH_M = 5.0


@dataclass(frozen=True)
class Stop:
    """A stop of the journey: distance from the start [m], planned arrival [s]."""

    distance_m: float
    planned_arrival_s: float


@dataclass(frozen=True)
class ClosedLoopRecord:
    times_s: FloatArray
    speeds_mps: FloatArray
    reference_speeds_mps: FloatArray
    accelerations_mps2: FloatArray
    max_overspeed_mps: float
    arrivals: dict[int, tuple[float, float]]
    """Stop index → (arrival time [s], stop error [m])."""
    traction_energy_j: float
    nmpc: NmpcStats
    coast_steps: int = 0
    """Control steps on which the train coasted with the plan (the NMPC left out, no solve)."""


def run_autonomous_journey(
    plan: OdpPlan,
    *,
    stops: list[Stop],
    model: PointMassParameters,
    truth: PointMassParameters,
    controller: NmpcController,
    duration_s: float,
    plant_step_s: float = 0.01,
) -> ClosedLoopRecord:
    """Drive the plan with the NMPC (model ``model``) on a plant with parameters ``truth``."""
    track_map = plan.track_map
    driving = AutonomousDriving(plan, model, controller)
    plant = PointMassModel(truth)
    control_s = controller.config.step_s
    substeps = round(control_s / plant_step_s)
    times, speeds, references, accelerations = [], [], [], []
    overspeed = -np.inf
    arrivals: dict[int, tuple[float, float]] = {}
    coast_steps = 0
    for k in range(round(duration_s / control_s)):
        now = k * control_s
        force = driving.force_n(
            now,
            distance_m=plant.position_m,
            speed_mps=plant.speed_mps,
            applied_force_n=plant.applied_force_n,
        )
        coast_steps += driving.coasting
        for _ in range(substeps):
            chainage = plan.chainage_m(plant.position_m)
            plant.step(
                plant_step_s,
                force,
                gradient_permille=track_map.gradient_permille(chainage),
                curve_radius_m=track_map.curve_radius_m(chainage),
            )
            overspeed = max(overspeed, plant.speed_mps - track_map.mrsp_mps(chainage))
        times.append(now + control_s)
        speeds.append(plant.speed_mps)
        references.append(plan.reference(now + control_s)[1])
        accelerations.append(plant.acceleration_mps2)
        _note_arrival(arrivals, stops, now + control_s, plant)
    return ClosedLoopRecord(
        times_s=np.array(times),
        speeds_mps=np.array(speeds),
        reference_speeds_mps=np.array(references),
        accelerations_mps2=np.array(accelerations),
        max_overspeed_mps=float(overspeed),
        arrivals=arrivals,
        traction_energy_j=plant.traction_energy_j,
        nmpc=controller.stats,
        coast_steps=coast_steps,
    )


def _note_arrival(
    arrivals: dict[int, tuple[float, float]], stops: list[Stop], at_s: float, plant: PointMassModel
) -> None:
    if plant.speed_mps >= STOPPED_MPS:
        return
    for index, stop in enumerate(stops):
        near = abs(plant.position_m - stop.distance_m) < STOP_SEARCH_M
        if index not in arrivals and near:
            arrivals[index] = (at_s, plant.position_m - stop.distance_m)


@dataclass(frozen=True)
class HandoverRecord:
    times_s: FloatArray
    forces_n: FloatArray
    """Force the SC applied at each control step [N]."""
    speeds_mps: FloatArray
    states: list[str]
    switch_indices: list[int]
    """Steps at which the SC changed state."""
    switch_jumps_n: list[float]
    """|u(t+) − u(t−)| at each change of state, both taken at the switching instant [N]."""


def run_handover_sequence(
    track_map: TrackMap,
    *,
    model: PointMassParameters,
    truth: PointMassParameters,
    start_chainage_m: float = 200.0,
    control_s: float = 0.2,
    plant_step_s: float = 0.01,
) -> HandoverRecord:
    """RD → AD → RD: remote driving at 30 km/h, autonomous towards a stop 1200 m ahead at
    40 km/h from t = 40 s, remote driving at 20 km/h from t = 100 s, until t = 160 s."""
    rig = _HandoverRig.build(
        track_map,
        model=model,
        truth=truth,
        start_chainage_m=start_chainage_m,
        control_s=control_s,
        plant_step_s=plant_step_s,
    )
    trace = _HandoverTrace()
    for k in range(round(160.0 / control_s)):
        now = k * control_s
        gradient = track_map.gradient_permille(rig.chainage_m())
        requests = rig.scheduled_requests(k, now, gradient, trace.forces)
        limits = rig.plant.force_limits_n(rig.plant.speed_mps)
        outputs = rig.controller_outputs(now, gradient, limits, requests)
        applied = rig.supervise(k, now, outputs, requests, limits, trace)
        rig.advance_plant(applied)
        trace.add(now, applied, rig.plant.speed_mps, rig.sc.state.value)
    return trace.record()


@dataclass
class _HandoverTrace:
    """What the hand-over sequence notes at each control step, and at each change of state."""

    times: list[float] = field(default_factory=list)
    forces: list[float] = field(default_factory=list)
    speeds: list[float] = field(default_factory=list)
    states: list[str] = field(default_factory=list)
    switches: list[int] = field(default_factory=list)
    jumps: list[float] = field(default_factory=list)

    def add(self, now_s: float, force_n: float, speed_mps: float, state: str) -> None:
        self.times.append(now_s)
        self.forces.append(force_n)
        self.speeds.append(speed_mps)
        self.states.append(state)

    def record(self) -> HandoverRecord:
        return HandoverRecord(
            times_s=np.array(self.times),
            forces_n=np.array(self.forces),
            speeds_mps=np.array(self.speeds),
            states=self.states,
            switch_indices=sorted(set(self.switches)),
            switch_jumps_n=self.jumps,
        )


@dataclass
class _HandoverRig:
    """The plant, the SC and both controllers of the hand-over sequence, and the RD target."""

    track_map: TrackMap
    model: PointMassParameters
    plant: PointMassModel
    sc: SupervisoryController
    rd: RemoteDrivingController
    nmpc: NmpcController
    start_chainage_m: float
    control_s: float
    plant_step_s: float
    autonomous: AutonomousDriving | None = None
    target_mps: float = 30 * MPS_PER_KMH

    @classmethod
    def build(
        cls,
        track_map: TrackMap,
        *,
        model: PointMassParameters,
        truth: PointMassParameters,
        start_chainage_m: float,
        control_s: float,
        plant_step_s: float,
    ) -> _HandoverRig:
        """Everything at rest, the SC asked for remote driving at t = 0."""
        plant = PointMassModel(truth)
        sc = SupervisoryController()
        rd = RemoteDrivingController(
            mass_kg=model.mass_kg,
            rolling_coefficient=model.davis_a_n / (model.mass_kg * GRAVITY_MPS2),
        )
        nmpc = NmpcController(model, NmpcConfig(step_s=control_s))
        sc.request(ModeRequest.REMOTE, 0.0)
        return cls(
            track_map=track_map,
            model=model,
            plant=plant,
            sc=sc,
            rd=rd,
            nmpc=nmpc,
            start_chainage_m=start_chainage_m,
            control_s=control_s,
            plant_step_s=plant_step_s,
        )

    def chainage_m(self) -> float:
        """The plant's chainage on the line [m]."""
        return self.track_map.normalise(self.start_chainage_m + self.plant.position_m)

    def scheduled_requests(
        self, k: int, now_s: float, gradient_permille: float, forces_n: list[float]
    ) -> list[ModeRequest]:
        """The requests of step ``k``: AD on a plan from the current state at t = 40 s, RD at
        20 km/h, aligned on the last applied force of ``forces_n``, at t = 100 s."""
        requests: list[ModeRequest] = []
        if k == round(40.0 / self.control_s):
            plan = replan_from_state(
                self.track_map,
                self.model,
                now_s=now_s,
                start_chainage_m=self.start_chainage_m,
                distance_m=self.plant.position_m,
                speed_mps=self.plant.speed_mps,
                stop_distance_m=1200.0,
                cruise_mps=40 * MPS_PER_KMH,
            )
            self.autonomous = AutonomousDriving(plan, self.model, self.nmpc)
            requests.append(ModeRequest.AUTONOMOUS)
        if k == round(100.0 / self.control_s):
            self.target_mps = 20 * MPS_PER_KMH
            self.rd.align(
                forces_n[-1], speed_mps=self.plant.speed_mps, gradient_permille=gradient_permille
            )
            requests.append(ModeRequest.REMOTE)
        return requests

    def controller_outputs(
        self,
        now_s: float,
        gradient_permille: float,
        limits: tuple[float, float],
        requests: list[ModeRequest],
    ) -> dict[str, float]:
        """Both controllers' forces [N], each 0 while the SC does not need it."""
        u_rd = 0.0
        if self.sc.needs_remote:
            u_rd = self.rd.step(
                self.control_s,
                target_speed_mps=self.target_mps,
                speed_mps=self.plant.speed_mps,
                gradient_permille=gradient_permille,
                force_limits_n=limits,
            )
        u_ad = 0.0
        if self.autonomous is not None and (self.sc.needs_autonomous or requests):
            u_ad = self.autonomous.force_n(
                now_s,
                distance_m=self.plant.position_m,
                speed_mps=self.plant.speed_mps,
                applied_force_n=self.plant.applied_force_n,
            )
        return {"remote_force_n": u_rd, "autonomous_force_n": u_ad}

    def supervise(
        self,
        k: int,
        now_s: float,
        outputs: dict[str, float],
        requests: list[ModeRequest],
        limits: tuple[float, float],
        trace: _HandoverTrace,
    ) -> float:
        """Pass the requests to the SC and step it, noting the output's jump at each change of
        state; the force to apply [N] (full brake while the SC is OFF)."""
        sc = self.sc
        for mode in requests:
            old = sc.output(**outputs)
            sc.request(mode, now_s)
            trace.jumps.append(abs((sc.output(**outputs) or 0.0) - (old or 0.0)))
        before = sc.state
        old = sc.output(**outputs)
        force = sc.step(self.control_s, now_s, **outputs)
        if sc.state is not before:
            trace.jumps.append(abs((force or 0.0) - (old or 0.0)))
        applied = limits[0] if force is None else force
        if sc.state is not before or (k and trace.states[-1] != before.value):
            trace.switches.append(k)
        return applied

    def advance_plant(self, force_n: float) -> None:
        """One control step of the plant under ``force_n`` [N], in plant steps."""
        for _ in range(round(self.control_s / self.plant_step_s)):
            chainage = self.chainage_m()
            self.plant.step(
                self.plant_step_s,
                force_n,
                gradient_permille=self.track_map.gradient_permille(chainage),
                curve_radius_m=self.track_map.curve_radius_m(chainage),
            )
