"""What a scenario run records: the truth beside what the vehicle believed and did.

:class:`TelemetryRecorder` is an observer task on the onboard node's executive, after the plant
(every 10 ms): it keeps running maxima at that rate (overspeed against the MRSP at the true
position) and samples one row of telemetry every control period (200 ms): time, the truth
(position, speed, acceleration, applied force), the MRSP, the ADF's reference speed and state,
the ATO-OB state and ETCS mode, the localisation estimate, the Vital Control's EB, the energy.
It notes each stop at a journey stopping point (where the ADF, on its estimate, believes it
stands at one), with the true stopping error. The truth is used
for KPIs only; nothing onboard reads this recorder.

The columns go to ``telemetry.npz`` (numpy, no pickle) and the plots of the report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from deploy.scenario.kpi_model import EoaStop, VcIntervention
from onboard.node import TASK_TABLE, OnboardNode
from onboard.plant.interfaces import BogieTruth
from onboard.runtime.clock import NS_PER_S

__all__ = ["COLUMNS", "EoaStopRecord", "StopRecord", "TelemetryRecorder"]

RECORDER_PRIORITY = TASK_TABLE["sfa"].priority - 1
"""Right after the plant and the localisation: the truth and the estimate of this tick."""
SAMPLE_S = TASK_TABLE["control"].period_s
STANDSTILL_MPS = 0.01

COLUMNS = (
    "time_s",
    "position_m",
    "speed_mps",
    "acceleration_mps2",
    "force_n",
    "force_demand_n",
    "mrsp_mps",
    "reference_speed_mps",
    "permitted_speed_mps",
    "estimated_position_m",
    "sc_state",
    "ato_state",
    "etcs_mode",
    "vc_eb",
    "soc",
    "range_extender_kw",
    "traction_energy_j",
    "wheel_slip_mps",
    "etcs_position_m",
    "odometry_interval_m",
)
"""The telemetry's columns: floats but the three states (their names as strings)."""


@dataclass(frozen=True)
class StopRecord:
    name: str
    planned_arrival_s: float
    arrival_s: float
    """Journey time of the stop [s]."""
    stop_error_m: float
    """True front position − stopping point, along the journey [m]."""
    odometry_interval_m: float
    """ETCS's confidence interval at the stop: the larger of over- and under-reading [m]."""
    at_s: float
    """The run's simulated time of the stop [s] (trains' journeys start at their own times)."""


@dataclass
class EoaStopRecord:
    """The train standing before an end of authority it stopped for (one record an EoA)."""

    eoa_m: float
    """The EoA in the plant's coordinate (unwrapped) [m]."""
    time_s: float
    """When the train came to stand at ``distance_to_eoa_m`` [s]."""
    distance_to_eoa_m: float
    """True front end to the EoA at the last standstill before it [m] (< 0: passed)."""
    odometry_interval_m: float
    """ETCS's confidence interval then (the larger of over- and under-reading) [m]."""

    def as_kpi(self) -> EoaStop:
        return EoaStop(
            time_s=self.time_s,
            distance_to_eoa_m=self.distance_to_eoa_m,
            odometry_interval_m=self.odometry_interval_m,
        )


EOA_SAME_M = 0.5
"""Two ends of authority closer than this [m] are one (the estimate moves the measure a bit)."""
EOA_SETTLED_S = 0.5
"""How long an EoA stays put before a standstill counts as a stop for it [s]: more than the
ADF's control period, in which it follows a new one."""


@dataclass
class _Maxima:
    overspeed_mps: float = -math.inf
    vc_eb_count: int = 0
    """Emergency brakes commanded by the Vital Control (rising edges of its valves' state)."""
    eoa_margin_m: float = math.inf
    """Least distance from the true front end to the ETCS end of authority [m] (< 0: passed)."""
    obstacle_margin_m: float = math.inf
    """Least distance from the true front end to the obstacle [m] (< 0: reached)."""
    outside_interval_m: float = 0.0
    """Furthest the true front end was outside ETCS's confidence interval [m] (0: never)."""
    over_cap_mps: float = -math.inf
    """Most the true speed exceeded the journey's cap while driving in AD [m/s]."""


@dataclass
class _Intervention:
    cause: str
    command_s: float
    hazard_s: float | None
    full_s: float | None = None

    def as_kpi(self) -> VcIntervention:
        def ms(end_s: float | None) -> float | None:
            if end_s is None or self.hazard_s is None:
                return None
            return round((end_s - self.hazard_s) * 1000.0, 3)

        return VcIntervention(
            cause=self.cause,
            hazard_to_eb_command_ms=ms(self.command_s),
            total_to_full_eb_ms=ms(self.full_s),
        )


@dataclass
class TelemetryRecorder:
    """Samples a node's truth and estimates; register it once on the node's executive."""

    node: OnboardNode
    rows: dict[str, list[float | str]] = field(default_factory=lambda: {c: [] for c in COLUMNS})
    stops: list[StopRecord] = field(default_factory=list)
    eoa_stops: list[EoaStopRecord] = field(default_factory=list)
    """Where the ADF stood still for an EoA short of its next stop (on its plan), measured on
    the truth."""
    maxima: _Maxima = field(default_factory=_Maxima)
    obstacle_m: float | None = None
    """An obstacle's position in the plant's coordinate (unwrapped), once there is one [m]."""
    cap_mps: float | None = None
    """The journey's speed cap, when it has one [m/s]."""
    sensor_lost_s: dict[str, float] = field(default_factory=dict)
    """When the localisation first reported each sensor (imu, odometer, gps) not alive [s]."""
    hazards_s: list[float] = field(default_factory=list)
    """When injected hazards began [s] (the runner notes them): an EB is timed from the last."""
    interventions: list[_Intervention] = field(default_factory=list)
    _next_sample_ns: int = 0
    _stopped_at: str | None = None
    _standing_since_s: float | None = None
    _stopped_for_authority: bool = False
    _eoa_seen: tuple[float, float] | None = None
    _eb: bool = False

    def register(self) -> None:
        vital = self.node.stack.vital
        self._eb = vital is not None and vital.eb_commanded  # powered up braked: no intervention
        self.node.executive.add_task(
            "telemetry",
            self._step,
            period_s=TASK_TABLE["plant"].period_s,
            priority=RECORDER_PRIORITY,
        )

    def _step(self, now_ns: int) -> None:
        node = self.node
        plant, track_map = node.plant, node.track_map
        chainage = track_map.normalise(plant.position_m)
        overspeed = plant.speed_mps - track_map.mrsp_mps(chainage)
        maxima = self.maxima
        maxima.overspeed_mps = max(maxima.overspeed_mps, overspeed)
        if self.cap_mps is not None and node.stack.driving.state.value == "AD":
            maxima.over_cap_mps = max(maxima.over_cap_mps, plant.speed_mps - self.cap_mps)
        etcs = node.stack.etcs.output
        if etcs is not None and etcs.end_of_authority_distance_m is not None:
            eoa_m = etcs.odometry.estimated_front_m + etcs.end_of_authority_distance_m
            maxima.eoa_margin_m = min(maxima.eoa_margin_m, eoa_m - plant.position_m)
            self._note_eoa_stop(now_ns / NS_PER_S, eoa_m)
        interval = node.stack.etcs.odometry
        outside_m = max(
            plant.position_m - interval.max_safe_front_m,
            interval.min_safe_front_m - plant.position_m,
        )
        maxima.outside_interval_m = max(maxima.outside_interval_m, outside_m)
        if self.obstacle_m is not None:
            maxima.obstacle_margin_m = min(
                maxima.obstacle_margin_m, self.obstacle_m - plant.position_m
            )
        self._note_stop(now_ns)
        self._note_emergency_brake(now_ns / NS_PER_S)
        self._note_sensors(now_ns / NS_PER_S)
        if now_ns >= self._next_sample_ns:
            self._next_sample_ns = now_ns + round(SAMPLE_S * NS_PER_S)
            self._sample(now_ns)

    def _note_eoa_stop(self, now_s: float, eoa_m: float) -> None:
        """A standstill for an EoA that has stayed put for :data:`EOA_SETTLED_S` (the ADF takes
        a control period to follow a new one)."""
        node = self.node
        if self._eoa_seen is None or abs(self._eoa_seen[0] - eoa_m) >= EOA_SAME_M:
            self._eoa_seen = (eoa_m, now_s)
        if node.plant.speed_mps > STANDSTILL_MPS:
            self._standing_since_s = None
            return
        if self._standing_since_s is None:
            # A standstill counts when the train came to it stopping for the EoA: one at a
            # stop that leaves towards an EoA short of the next stop is not one.
            self._standing_since_s = now_s
            self._stopped_for_authority = node.stack.driving.stopping_for_authority
        settled = now_s - self._eoa_seen[1] >= EOA_SETTLED_S
        # An EoA that moved while the train stood (an MA extended before it moved off) is not
        # one it stopped for.
        in_force = self._eoa_seen[1] <= self._standing_since_s
        if not (
            settled
            and in_force
            and self._stopped_for_authority
            and node.stack.driving.stopping_for_authority
        ):
            return
        distance_m = eoa_m - node.plant.position_m
        last = self.eoa_stops[-1] if self.eoa_stops else None
        if last is not None and abs(last.eoa_m - eoa_m) < EOA_SAME_M:
            last.time_s = self._standing_since_s
            last.distance_to_eoa_m = distance_m
            last.odometry_interval_m = _interval_m(node)
            return
        self.eoa_stops.append(
            EoaStopRecord(eoa_m, self._standing_since_s, distance_m, _interval_m(node))
        )

    def _note_sensors(self, now_s: float) -> None:
        chain = self.node.sensor_fusion
        estimate = None if chain is None else chain.estimate
        if estimate is None:
            return
        for name, alive in (
            ("imu", estimate.imu_alive),
            ("odometer", estimate.odometer_alive),
            ("gps", estimate.gps_alive),
        ):
            if alive is False and name not in self.sensor_lost_s:
                self.sensor_lost_s[name] = now_s

    def _note_emergency_brake(self, now_s: float) -> None:
        vital = self.node.stack.vital
        if vital is None:
            return
        eb = vital.eb_commanded
        if eb and not self._eb:
            self.maxima.vc_eb_count += 1
            status = self.node.stack.vital_status()
            conditions = () if status is None else status.eb_conditions
            cause = ",".join(f"eb{c}" for c in conditions) or (
                "operator" if status is not None and not status.system_decay else "vc"
            )
            hazard = max((h for h in self.hazards_s if h <= now_s), default=None)
            self.interventions.append(_Intervention(cause, now_s, hazard))
        self._eb = eb
        last = self.interventions[-1] if self.interventions else None
        if last is not None and last.full_s is None and vital.emergency_brake(now_s) >= 1.0:
            last.full_s = now_s

    @property
    def vc_interventions(self) -> list[VcIntervention]:
        """``kpis.json``'s ``vc_interventions``: hazard → EB command, hazard → full EB."""
        return [item.as_kpi() for item in self.interventions]

    def _note_stop(self, now_ns: int) -> None:
        node = self.node
        driving = node.stack.driving
        if driving.journey is None or node.plant.speed_mps > STANDSTILL_MPS:
            self._stopped_at = None
            return
        # The stop the ADF believes it stands at (on its estimate); its error is the truth's.
        stop = driving.stopped_at(node.stack.position_m, node.stack.speed_mps)
        if stop is None or stop.timing_point_id == self._stopped_at:
            return
        self._stopped_at = stop.timing_point_id
        if any(record.name == stop.timing_point_id for record in self.stops):
            return
        travelled = node.plant.position_m - driving.progress.origin_m
        self.stops.append(
            StopRecord(
                name=stop.timing_point_id,
                planned_arrival_s=stop.arrival_s,
                arrival_s=driving.journey_time_s(now_ns / NS_PER_S),
                stop_error_m=travelled - stop.distance_m,
                odometry_interval_m=_interval_m(node),
                at_s=now_ns / NS_PER_S,
            )
        )

    def _sample(self, now_ns: int) -> None:
        node = self.node
        now_s = now_ns / NS_PER_S
        plant, stack = node.plant, node.stack
        chainage = node.track_map.normalise(plant.position_m)
        etcs = stack.etcs.output
        powertrain = getattr(plant, "powertrain", None)
        soc = getattr(powertrain, "soc", math.nan)
        extender = getattr(powertrain, "range_extender", None)
        extender_kw = math.nan if extender is None else extender.power_w / 1000.0
        values: dict[str, float | str] = {
            "time_s": now_s,
            "position_m": plant.position_m,
            "speed_mps": plant.speed_mps,
            "acceleration_mps2": plant.acceleration_mps2,
            "force_n": plant.applied_force_n,
            "force_demand_n": stack.force_demand_n,
            "mrsp_mps": node.track_map.mrsp_mps(chainage),
            "reference_speed_mps": _nan_if_none(stack.driving.reference_speed_mps(now_s)),
            "permitted_speed_mps": math.nan if etcs is None else etcs.permitted_speed_mps,
            "estimated_position_m": stack.position_m,
            "sc_state": stack.driving.state.value,
            "ato_state": stack.ato_state.value,
            "etcs_mode": stack.etcs.mode.value,
            "vc_eb": float(stack.vital is not None and stack.vital.eb_commanded),
            "soc": float(soc),
            "range_extender_kw": extender_kw,
            "traction_energy_j": plant.traction_energy_j,
            "wheel_slip_mps": _wheel_slip_mps(plant),
            "etcs_position_m": stack.etcs.odometry.estimated_front_m,
            "odometry_interval_m": _interval_m(node),
        }
        for column in COLUMNS:
            self.rows[column].append(values[column])

    def arrays(self) -> dict[str, np.ndarray]:
        """The columns as arrays: floats, or strings for the states."""
        return {
            column: np.asarray(values, dtype=str if column.endswith(("_state", "_mode")) else float)
            for column, values in self.rows.items()
        }

    def save(self, path: Path) -> None:
        """``telemetry.npz``: one array per column (``numpy.load(path)`` reads it)."""
        arrays: dict[str, Any] = dict(self.arrays())
        np.savez_compressed(path, **arrays)


def _wheel_slip_mps(plant: object) -> float:
    """The larger of the two wheelsets' |ω·r − v| on the bogie model [m/s]; NaN on the point
    mass, whose wheels do not slip."""
    truth = getattr(getattr(plant, "dynamics", None), "truth", None)
    if not isinstance(truth, BogieTruth):
        return math.nan
    radius, speed = truth.wheel_radius_m, truth.speed_mps
    return max(
        abs(truth.wheel_speed_front_radps * radius - speed),
        abs(truth.wheel_speed_rear_radps * radius - speed),
    )


def _interval_m(node: OnboardNode) -> float:
    """ETCS's confidence interval now: the larger of over- and under-reading [m]."""
    interval = node.stack.etcs.odometry
    return max(interval.over_reading_m, interval.under_reading_m)


def _nan_if_none(value: float | None) -> float:
    return math.nan if value is None else value
