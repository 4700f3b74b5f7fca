"""``ato run``: one scenario with the whole stack in one process.

The trackside service (its FastAPI app, in process, on a SQLite file in a scratch directory),
the onboard node and the simulated operator run in this process; the trackside's Zenoh session
listens on a free loopback port and the onboard's session connects to it, so every message
crosses a real Zenoh link; the operator's commands leave from the trackside's session, as the
console's do. The onboard runs in lockstep on a :class:`SimClock`
(``fast``) or paced at wall time × ``speed`` on a :class:`RealTimeClock`; either way the runner
advances it in slices of :data:`SLICE_S` and acts between slices, as an operator at the console
would: the scenario's actions in file order, each once its time and its condition hold; the
simulated operator's answers to the Vital Control; the faults as their time comes.

A telemetry recorder on the node's executive samples the truth; at the end the KPIs
(CONTRACT.md §4) are computed and the expectations checked, and with a report directory
``kpis.json``, ``telemetry.npz`` and ``report.html`` are written.

Scenarios with a ``[vc]`` table run one scenario of the Vital Control catalogue instead
(``deploy.bench.vc_runner``): the VC library with its emulated I/O in lockstep, on a scripted train.
"""

from __future__ import annotations

import json
import math
import secrets
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import zenoh
from fastapi.testclient import TestClient

from deploy.bench.vc_runner import ScenarioResult
from deploy.bench.vc_runner import run_scenario as run_vc_scenario
from deploy.link_proxy import LinkProxy
from deploy.ports import loopback_endpoint
from deploy.scenario.conditions import State
from deploy.scenario.invariants import invariant_expectations
from deploy.scenario.kpis import (
    RunCounters,
    check_expectations,
    compute_kpis,
    odometry_interval_kpi,
)
from deploy.scenario.report import render_report
from deploy.scenario.schema import (
    Action,
    AtoFailure,
    BaliseMissed,
    Fault,
    FrictionDrop,
    Obstacle,
    OdometerFailure,
    RelayFault,
    ScenarioSpec,
    SensorDropout,
    ShortenedAuthority,
    TachometerFault,
    TemporarySpeedRestriction,
    TracksideRestart,
    UdpLinkFault,
    VigilanceAbsent,
    WheelDiameterError,
    ZenohLinkLoss,
)
from deploy.scenario.telemetry import TelemetryRecorder
from deploy.scenario.zenoh_link import ZenohLinkFault
from onboard.ato_ob.transitions import Trigger
from onboard.node import OnboardNode, OnboardSettings
from onboard.plant.sensors import SensorFaults, TimeWindow
from onboard.runtime import RealTimeClock, SimClock, TaskStats
from onboard.sfa.chain import SensorSettings
from onboard.sfa.link import LinkFaults
from onboard.vc import hardware as vc_hardware
from onboard.vc.installation import VcFaults
from protocol import ZenohSettings, open_session
from protocol import messages as m
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap, load_seed_line
from trackside.config import Settings
from trackside.main import create_app

__all__ = ["SLICE_S", "Progress", "RunOptions", "RunOutcome", "ScenarioRunError", "run_scenario"]

SLICE_S = 0.2
"""Simulated time between two looks of the operator [s] (one control period)."""
STANDSTILL_KMH = 0.036
JOURNEY_TIMEOUT_S = 10.0
"""How long the operator waits for the vehicle's journey acknowledgement [s, simulated]."""
WAIT_S = 10.0
"""How long, in wall time, a message sent to the vehicle may take to reach it [s]."""
LINK_WAIT_S = 15.0
"""How long, in wall time, the sessions may take to notice a cut or a restored link [s]."""
OBSTACLE_MARGIN_M = 20.0
"""The RBC ends the MA this far before a reported obstacle [m]."""
VC_DATALOG = "vc-datalog.jsonl"
"""The VC's datalog in a run's report directory (``ato vc replay`` reads it)."""
WHOLE_STACK_FAULTS = (
    AtoFailure,
    FrictionDrop,
    Obstacle,
    OdometerFailure,
    RelayFault,
    SensorDropout,
    ShortenedAuthority,
    TachometerFault,
    TemporarySpeedRestriction,
    TracksideRestart,
    UdpLinkFault,
    VigilanceAbsent,
    ZenohLinkLoss,
    WheelDiameterError,
    BaliseMissed,
)
"""The faults a whole-stack run injects (docs/scenarios.md)."""


class ScenarioRunError(RuntimeError):
    """The run could not be carried out (not: an expectation failed)."""


@dataclass(frozen=True)
class RunOptions:
    fast: bool = True
    """Lockstep, as fast as possible; otherwise paced at wall time × ``speed``."""
    speed: float = 1.0
    seed: int | None = None
    """Overrides the scenario's seed."""
    report_dir: Path | None = None


@dataclass(frozen=True)
class Progress:
    """What the progress bar shows, once per slice."""

    sim_time_s: float
    duration_s: float
    speed_kmh: float
    etcs_mode: str
    ato_state: str
    sc_state: str


@dataclass
class RunOutcome:
    kpis: dict[str, Any]
    columns: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        return bool(self.kpis["passed"])


ProgressCallback = Callable[[Progress], None]


def run_scenario(
    spec: ScenarioSpec,
    options: RunOptions = RunOptions(),
    *,
    progress: ProgressCallback | None = None,
) -> RunOutcome:
    """Run ``spec``; the outcome's ``kpis`` follow CONTRACT.md §4."""
    seed = spec.seed if options.seed is None else options.seed
    started = time.perf_counter()
    if spec.vc is not None:
        outcome = _run_vc(spec, seed)
    else:
        with _Stack.open(spec, options, seed) as stack:
            outcome = stack.run(progress)
    wall_s = time.perf_counter() - started
    sim_s = float(outcome.kpis["sim_time_s"])
    outcome.kpis.update(
        wall_time_s=wall_s, real_time_factor=sim_s / wall_s if wall_s > 0 else math.inf
    )
    breakdown = outcome.kpis.get("wall_time_breakdown")
    if breakdown is not None:
        breakdown["outside_lockstep_s"] = round(wall_s - breakdown["lockstep_s"], 3)
    if options.report_dir is not None:
        write_report(outcome, options.report_dir)
    return outcome


def write_report(outcome: RunOutcome, directory: Path) -> None:
    """``kpis.json``, and for whole-stack runs ``telemetry.npz`` and ``report.html``."""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "kpis.json").write_text(json.dumps(outcome.kpis, indent=2, allow_nan=False))
    if outcome.columns:
        np.savez_compressed(directory / "telemetry.npz", **outcome.columns)  # type: ignore[arg-type]
        (directory / "report.html").write_text(render_report(outcome.kpis, outcome.columns))


def _ordered_keys(kpis: dict[str, Any]) -> dict[str, Any]:
    first = ("scenario", "passed", "seed", "sim_time_s", "wall_time_s", "real_time_factor")
    return {key: kpis[key] for key in first if key in kpis} | {
        key: value for key, value in kpis.items() if key not in first
    }


# -- the Vital Control catalogue ---------------------------------------------------------------


def _ms(value: float | None) -> float | None:
    return None if value is None else round(value * 1000.0, 3)


def _run_vc(spec: ScenarioSpec, seed: int) -> RunOutcome:
    assert spec.vc is not None
    from deploy.bench.vc_catalogue import scenario as catalogue_scenario

    try:
        scenario = catalogue_scenario(spec.vc.catalogue)
    except KeyError as exc:
        raise ScenarioRunError(f"no VC catalogue scenario {spec.vc.catalogue!r}") from exc
    result = run_vc_scenario(scenario, replicas=spec.vc.replicas, seed=seed)
    kpis: dict[str, Any] = {
        "scenario": spec.name,
        "seed": seed,
        "sim_time_s": scenario.duration_s,
        "stops": [],
        "eoa_stops": [],
        "max_overspeed_kmh": 0.0,
        "etcs_sb_count": 0,
        "etcs_eb_count": 0,
        "vc_eb_count": sum(1 for e in result.events if e.kind.value == "eb_commanded"),
        "system_decay": result.decay_s is not None,
        "traction_energy_kwh": 0.0,
        "regen_energy_kwh": 0.0,
        "max_jerk_mps3": 0.0,
        "ad_speed_rms_kmh": None,
        "rd_speed_rms_kmh": None,
        "max_switch_du_frac": None,
        "position_error_m": {"rms": 0.0, "max": 0.0},
        "nmpc_ms": None,
        "nmpc_failures": 0,
        "nmpc_fallback_s": 0.0,
        "vc_interventions": _vc_interventions(result),
        "vc_outcome": result.outcome.value,
        "vc_expected_outcome": result.expected.value,
        "vc_decay_reasons": list(result.decay_reasons),
    }
    kpis["expectations"] = check_expectations(kpis, spec.expect)
    kpis["passed"] = all(item["ok"] for item in kpis["expectations"])
    return RunOutcome(_ordered_keys(kpis))


def _vc_interventions(result: ScenarioResult) -> list[dict[str, Any]]:
    if result.eb_command_s is None:
        return []
    hazard = result.hazard_s
    return [
        {
            "cause": result.key,
            "hazard_to_eb_command_ms": None
            if hazard is None
            else _ms(result.eb_command_s - hazard),
            "total_to_full_eb_ms": (
                None
                if hazard is None or result.full_eb_s is None
                else _ms(result.full_eb_s - hazard)
            ),
        }
    ]


# -- the whole stack ---------------------------------------------------------------------------


@dataclass
class _ActionLog:
    action: str
    at_s: float
    accepted: bool
    detail: str | None = None


class _Stack:
    """Trackside, onboard and operator of one run, wired together."""

    def __init__(
        self,
        spec: ScenarioSpec,
        options: RunOptions,
        seed: int,
        scratch: Path,
        trackside_zenoh: zenoh.Session,
        node: OnboardNode,
        link: ZenohLinkFault | None = None,
    ) -> None:
        self.spec, self.options, self.seed = spec, options, seed
        self.link = link
        self.trackside_zenoh = trackside_zenoh
        simulated = (spec.vehicle.id,) if spec.operator.simulated else ()
        self.settings = Settings(
            database_url=f"sqlite:///{scratch / 'trackside.db'}",
            zenoh_connect=(),
            admin_user="scenario",
            admin_password=secrets.token_urlsafe(16),
            simulated_operators=simulated,
            simulated_operator_reaction_s=spec.operator.reaction_s,
            simulated_operator_thread=False,
        )
        self.client: TestClient | None = None
        self.headers: dict[str, str] = {}
        self._selected = False
        self.node = node
        self.operator_present = spec.operator.simulated
        self.recorder = TelemetryRecorder(node)
        self.recorder.register()
        if spec.journey is not None and spec.journey.max_speed_kmh is not None:
            self.recorder.cap_mps = spec.journey.max_speed_kmh * MPS_PER_KMH
        self.recorder.hazards_s.extend(
            fault.start_s
            for fault in spec.faults
            if isinstance(fault, RelayFault | TachometerFault)
        )
        self.actions: list[_ActionLog] = []
        self.failures: list[str] = []
        self._next_action = 0
        self._armed_s = 0.0
        self._done: set[int] = set()
        """The one-shot faults already injected (by index)."""
        self._session_up = False
        self._ready_since_s: float | None = None
        self.lockstep_wall_s = 0.0
        """Wall time spent stepping the node (the rest is set-up, operator and REST)."""
        self.session_outages: list[dict[str, float | None]] = []
        """Each loss of an established session: when [s], and when one was established again."""

    @classmethod
    @contextmanager
    def open(cls, spec: ScenarioSpec, options: RunOptions, seed: int) -> Iterator[_Stack]:
        unwired = [f.kind for f in spec.faults if not isinstance(f, WHOLE_STACK_FAULTS)]
        if unwired:
            raise ScenarioRunError(f"faults not injected in whole-stack runs: {unwired}")
        if spec.vehicle.fidelity != "bogie" and any(
            isinstance(f, FrictionDrop) for f in spec.faults
        ):
            raise ScenarioRunError("friction_drop needs the bogie model (vehicle.fidelity)")
        with ExitStack() as stack:
            scratch = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="ato-run-")))
            endpoint = loopback_endpoint()
            trackside_zenoh = stack.enter_context(
                open_session(ZenohSettings(mode="peer", connect=(), listen=(endpoint,)))
            )
            # With a link fault the onboard reaches the trackside through a proxy that can cut
            # the link (closed after the sessions: the ExitStack unwinds in reverse).
            proxy = None
            connect = endpoint
            if any(isinstance(f, ZenohLinkLoss) for f in spec.faults):
                proxy = stack.enter_context(LinkProxy.to_endpoint(endpoint))
                connect = ZenohLinkFault.connect_endpoint(proxy)
            onboard_zenoh = stack.enter_context(
                open_session(ZenohSettings(mode="peer", connect=(connect,)))
            )
            link = None
            if proxy is not None:
                link = ZenohLinkFault(
                    proxy,
                    onboard=onboard_zenoh,
                    trackside=trackside_zenoh,
                    vehicle_id=spec.vehicle.id,
                )
                stack.callback(link.close)
            vehicle = spec.vehicle
            if options.report_dir is not None and vehicle.vc_datalog:
                options.report_dir.mkdir(parents=True, exist_ok=True)
            clock = SimClock() if options.fast else RealTimeClock(options.speed)
            node = OnboardNode(
                OnboardSettings(
                    vehicle_id=vehicle.id,
                    fidelity=vehicle.fidelity,
                    start_position_m=vehicle.start_position_m,
                    energy_plans=vehicle.energy_plans,
                    vc_replicas=vehicle.vc_replicas,
                    vc_faults=_vc_faults(spec.faults),
                    initial_soc=vehicle.initial_soc,
                    vc_datalog=(
                        (options.report_dir or scratch) / VC_DATALOG if vehicle.vc_datalog else None
                    ),
                    sensors=_sensor_settings(spec.faults, seed),
                ),
                session=onboard_zenoh,
                clock=clock,
                track_map=TrackMap(load_seed_line(spec.line)),
            )
            stack.callback(node.close)
            run = cls(spec, options, seed, scratch, trackside_zenoh, node, link)
            run.start_trackside()
            stack.callback(run.stop_trackside)
            yield run

    def start_trackside(self) -> None:
        """The service (a new app on the same database and Zenoh session), and a login."""
        client = TestClient(create_app(self.settings, zenoh_session=self.trackside_zenoh))
        client.__enter__()
        self.client = client
        password = self.settings.admin_password
        assert password is not None
        answer = client.post(
            "/api/v1/auth/token",
            data={
                "username": "scenario",
                "password": password.get_secret_value(),
            },
        )
        self.headers = {"Authorization": f"Bearer {answer.json()['access_token']}"}
        self._selected = False

    def _select(self) -> None:
        """Hold the vehicle, as a driver at the console does before commanding it (once the
        trackside has seen it; the hold is stored, selecting again is harmless)."""
        if self._selected:
            return
        url = f"/api/v1/vehicles/{self.spec.vehicle.id}"
        if not _wait(lambda: self.rest.get(url, headers=self.headers).status_code == 200):
            raise ScenarioRunError("the trackside never saw the vehicle")
        selected = self.rest.post(f"{url}/select", headers=self.headers)
        if selected.status_code != 200:
            raise ScenarioRunError(f"cannot select the vehicle: {selected.text[:200]}")
        self._selected = True

    def stop_trackside(self) -> None:
        if self.client is not None:
            self.client.__exit__(None, None, None)
            self.client = None

    @property
    def rest(self) -> TestClient:
        if self.client is None:
            raise ScenarioRunError("the trackside is down")
        return self.client

    # -- the loop ------------------------------------------------------------------------------

    def run(self, progress: ProgressCallback | None) -> RunOutcome:
        spec, node = self.spec, self.node
        end_when = None if spec.end_when is None else _condition(spec.end_when)
        # The first handshake is due at the first tick: it is made once the onboard sees the
        # trackside, however long the two sessions take to meet in wall time.
        if not _wait(lambda: node.trackside_seen, timeout_s=LINK_WAIT_S):
            raise ScenarioRunError("the onboard never saw the trackside")
        while node.clock.now_s < spec.duration_s - 1e-9:
            state = self.state()
            if end_when is not None and end_when(state):
                break
            self._faults(node.clock.now_s, state)
            if not self._act(state):
                break
            self._answer_vc()
            self._reengage(state)
            self._run(min(SLICE_S, spec.duration_s - node.clock.now_s))
            self._watch_session()
            if progress is not None:
                progress(self._progress())
        if self._next_action < len(spec.actions):
            pending = spec.actions[self._next_action]
            self.failures.append(f"action {self._next_action + 1} ({pending.do}) never happened")
        return self._outcome()

    def _run(self, duration_s: float) -> None:
        started = time.perf_counter()
        self.node.run(duration_s)
        self.lockstep_wall_s += time.perf_counter() - started

    def _watch_session(self) -> None:
        """Note each loss of the established session and its re-establishment (to the slice)."""
        established = self.node.session_client.established
        if established == self._session_up:
            return
        self._session_up = established
        now_s = round(self.node.clock.now_s, 6)
        if not established:
            self.session_outages.append(
                {"lost_s": now_s, "reestablished_s": None, "duration_s": None}
            )
        elif self.session_outages and self.session_outages[-1]["reestablished_s"] is None:
            outage = self.session_outages[-1]
            lost_s = outage["lost_s"]
            assert lost_s is not None
            outage.update(reestablished_s=now_s, duration_s=round(now_s - lost_s, 6))

    def _progress(self) -> Progress:
        stack = self.node.stack
        return Progress(
            sim_time_s=self.node.clock.now_s,
            duration_s=self.spec.duration_s,
            speed_kmh=self.node.plant.speed_mps / MPS_PER_KMH,
            etcs_mode=stack.etcs.mode.value,
            ato_state=stack.ato_state.value,
            sc_state=stack.driving.state.value,
        )

    def state(self) -> State:
        """The fields of ``deploy.scenario.conditions`` now."""
        node = self.node
        stack, plant = node.stack, node.plant
        vital = stack.vital
        driving = stack.driving
        standstill = plant.speed_mps / MPS_PER_KMH < STANDSTILL_KMH
        next_stop = None if driving.journey is None else driving.next_stop(plant.position_m)
        ended = driving.journey is not None and next_stop is None and standstill
        etcs = stack.etcs.output
        eoa_distance_m = (
            math.inf
            if etcs is None or etcs.end_of_authority_distance_m is None
            else etcs.end_of_authority_distance_m
        )
        return {
            "time_s": node.clock.now_s,
            "position_m": node.track_map.normalise(plant.position_m),
            "speed_kmh": plant.speed_mps / MPS_PER_KMH,
            "etcs_mode": stack.etcs.mode.value,
            "ato_state": stack.ato_state.value,
            "sc_state": driving.state.value,
            "standstill": standstill,
            "vc_eb": vital is not None and vital.eb_commanded,
            "vc_decay": vital is not None and vital.outputs.system_decay,
            "journey_accepted": stack.journey_plan is not None,
            "journey_ended": ended,
            "etcs_braked": (
                stack.etcs.service_brake_interventions + stack.etcs.emergency_brake_interventions
            )
            > 0,
            "next_stop": "none" if next_stop is None else next_stop.timing_point_id,
            "eoa_distance_m": eoa_distance_m,
        }

    # -- faults --------------------------------------------------------------------------------

    def _faults(self, now_s: float, state: State) -> None:
        present = self.spec.operator.simulated
        internal_fault = False
        adhesion = 1.0
        link_lost: ZenohLinkLoss | None = None
        for index, fault in enumerate(self.spec.faults):
            if isinstance(fault, VigilanceAbsent):
                present &= not fault.start_s <= now_s < fault.end_s
            elif isinstance(fault, ZenohLinkLoss):
                if link_lost is None and fault.start_s <= now_s < fault.end_s:
                    link_lost = fault
            elif isinstance(fault, AtoFailure):
                active = fault.start_s <= now_s < fault.end_s
                if active and not self.node.stack.internal_fault and not internal_fault:
                    self.recorder.hazards_s.append(now_s)
                internal_fault |= active
            elif isinstance(fault, FrictionDrop) and fault.start_s <= now_s < fault.end_s:
                adhesion = min(adhesion, fault.factor)
            elif isinstance(fault, Obstacle | ShortenedAuthority | TracksideRestart):
                if index not in self._done and _fault_due(fault, now_s, state):
                    self._done.add(index)
                    self.recorder.hazards_s.append(now_s)
                    self._inject(fault)
            elif (
                isinstance(fault, TemporarySpeedRestriction)
                and index not in self._done
                and _fault_due(fault, now_s, state)
            ):
                self._done.add(index)
                self._speed_restriction(f"tsr-{index + 1}", fault)
        self._zenoh_link(link_lost)
        # The operator at the console sees the vehicle only over the link, and answers through it.
        self.operator_present = present and link_lost is None
        self.node.stack.internal_fault = internal_fault
        self.node.plant.adhesion_factor = adhesion

    def _zenoh_link(self, lost: ZenohLinkLoss | None) -> None:
        """Cut the onboard ↔ trackside link when a window opens, restore it when none is open;
        the simulation stands still, in wall time, until both sides have seen the change."""
        link = self.link
        if link is None or link.up == (lost is None):
            return
        now_s = self.node.clock.now_s
        if lost is not None:
            # The acknowledgement of the report in flight arrives first, however slow the wire:
            # the loss then starts at this tick in every run.
            if not _wait(lambda: not self.node.status_ack_outstanding):
                raise ScenarioRunError("the status acknowledgement before the cut never came")
            if not link.cut(lost.mode, timeout_s=LINK_WAIT_S):
                raise ScenarioRunError("the sessions did not notice the lost Zenoh link")
            self.recorder.hazards_s.append(now_s)
            self.actions.append(_ActionLog("link.cut", now_s, True, lost.mode))
        else:
            if not link.restore(timeout_s=LINK_WAIT_S):
                raise ScenarioRunError("the Zenoh link did not come back")
            self.actions.append(_ActionLog("link.restore", now_s, True))

    def _inject(self, fault: Fault) -> None:
        if isinstance(fault, TracksideRestart):
            self.stop_trackside()
            self._run(fault.down_s)
            self.start_trackside()
            return
        track_map, plant = self.node.track_map, self.node.plant
        here = track_map.normalise(plant.position_m)
        if isinstance(fault, Obstacle):
            ahead = _forward_m(self.node, here, fault.position_m)
            self.recorder.obstacle_m = plant.position_m + ahead
            end_m = here + ahead - OBSTACLE_MARGIN_M
            danger_m = 0.0
        else:
            assert isinstance(fault, ShortenedAuthority)
            end_m = here + _forward_m(self.node, here, fault.end_of_authority_m)
            danger_m = fault.danger_point_m
        answer = self._movement_authority(end_m, absolute=True, danger_point_m=danger_m)
        accepted = answer.status_code in (200, 201)
        self.actions.append(
            _ActionLog(f"rbc.{fault.kind}", self.node.clock.now_s, accepted, answer.text[:200])
        )

    def _speed_restriction(self, restriction_id: str, fault: TemporarySpeedRestriction) -> None:
        """The RBC (REST, as admin) sends a TSR; the run goes on once the vehicle has it."""
        before = self.node.inputs_received[2]
        body = {
            "id": restriction_id,
            "line_id": self.spec.line,
            "start_m": fault.start_m,
            "end_m": fault.end_m,
            "speed_kmh": fault.speed_kmh,
        }
        answer = self.rest.post(
            f"/api/v1/rbc/{self.spec.vehicle.id}/tsr", json=body, headers=self.headers
        )
        accepted = answer.status_code == 201
        self.actions.append(
            _ActionLog("rbc.tsr", self.node.clock.now_s, accepted, answer.text[:200])
        )
        if not accepted:
            self.failures.append(f"TSR {restriction_id} refused: {answer.text[:200]}")
        elif not _wait(lambda: self.node.inputs_received[2] > before):
            raise ScenarioRunError("the RBC's TSR never reached the vehicle")

    def _movement_authority(
        self, end_m: float, *, absolute: bool = False, danger_point_m: float = 0.0
    ) -> Any:
        """The RBC (REST, as admin) issues an MA from here to ``end_m`` (a chainage, or with
        ``absolute`` a position already unwrapped from here), or shortens the one it holds, its
        new end with ``danger_point_m``; the run goes on once the vehicle has the message."""
        here = self.node.track_map.normalise(self.node.plant.position_m)
        if not absolute:
            end_m = here + _forward_m(self.node, here, end_m)
        url = f"/api/v1/rbc/{self.spec.vehicle.id}/ma"
        before = self.node.inputs_received[1]
        if self.rest.get(url, headers=self.headers).status_code == 404 or not absolute:
            body = {
                "start_m": here,
                "end_of_authority_m": end_m,
                "line_id": self.spec.line,
                "danger_point_m": danger_point_m,
            }
            answer = self.rest.post(url, json=body, headers=self.headers)
        else:
            end = {"end_of_authority_m": end_m, "danger_point_m": danger_point_m}
            answer = self.rest.post(f"{url}/shorten", json=end, headers=self.headers)
        if answer.status_code in (200, 201) and not _wait(
            lambda: self.node.inputs_received[1] > before
        ):
            raise ScenarioRunError("the RBC's MA never reached the vehicle")
        return answer

    # -- actions -------------------------------------------------------------------------------

    def _act(self, state: State) -> bool:
        """Do the actions due now; False when one timed out (the run stops)."""
        actions = self.spec.actions
        while self._next_action < len(actions):
            action = actions[self._next_action]
            now_s = float(state["time_s"])
            if now_s - self._armed_s > action.timeout_s:
                self.failures.append(
                    f"action {self._next_action + 1} ({action.do}) timed out after "
                    f"{action.timeout_s:.0f} s"
                )
                return False
            if not self._due(action, state):
                return True
            self._do(action)
            self._next_action += 1
            self._armed_s = now_s
            state = self.state()
        return True

    def _due(self, action: Action, state: State) -> bool:
        now_s = float(state["time_s"])
        if action.at_s is not None and now_s < action.at_s:
            return False
        if action.after_s is not None and now_s < self._armed_s + action.after_s:
            return False
        condition = action.condition
        return condition is None or condition.holds(state)

    def _do(self, action: Action) -> None:
        now_s = self.node.clock.now_s
        self._select()
        if action.do == "issue_ma":
            assert action.end_of_authority_m is not None
            answer = self._movement_authority(action.end_of_authority_m)
            accepted = answer.status_code in (200, 201)
            self.actions.append(_ActionLog(action.do, now_s, accepted, answer.text[:200]))
            if not accepted:
                self.failures.append(f"issue_ma at {now_s:.1f} s refused: {answer.text[:200]}")
            return
        if action.do == "send_journey":
            accepted, detail = self._send_journey()
            self.actions.append(_ActionLog(action.do, now_s, accepted, detail))
            if not accepted:
                self.failures.append(f"journey refused: {detail}")
            return
        route, body = self._route(action)
        if route is None:
            self.actions.append(_ActionLog(action.do, now_s, False, "no such request pending"))
            self.failures.append(f"{action.do} at {now_s:.1f} s: no such request pending")
            return
        answer = self.rest.post(
            f"/api/v1/vehicles/{self.spec.vehicle.id}/{route}", json=body, headers=self.headers
        )
        if answer.status_code != 200:
            detail = f"{answer.status_code}: {answer.text[:200]}"
            self.actions.append(_ActionLog(action.do, now_s, False, detail))
            self.failures.append(f"{action.do} at {now_s:.1f} s failed: {detail}")
            return
        reply = answer.json()
        self.actions.append(_ActionLog(action.do, now_s, reply["accepted"], reply["reason"]))
        if not reply["accepted"]:
            self.failures.append(f"{action.do} at {now_s:.1f} s refused: {reply['reason']}")

    def _reengage(self, state: State) -> None:
        """``operator.reengage``: engage again once ATO has stood ready for the reaction time,
        after the journey was first engaged."""
        if not self.spec.operator.reengage:
            return
        engaged = any(log.action == "engage" and log.accepted for log in self.actions)
        now_s = float(state["time_s"])
        if not engaged or state["ato_state"] != m.AtoState.READY.value:
            self._ready_since_s = None
            return
        if self._ready_since_s is None:
            self._ready_since_s = now_s
        if now_s - self._ready_since_s >= self.spec.operator.reaction_s:
            self._ready_since_s = None
            self._do(Action(do="engage"))

    def _answer_vc(self) -> None:
        """The trackside's simulated operator looks at the vehicle's state now and answers what
        is due; the run goes on once the vehicle has its answers (so they reach it at a tick
        fixed by simulated time)."""
        if not self.operator_present or self.client is None:
            return
        thread = self.client.app.state.simulated_operator  # type: ignore[attr-defined]
        if thread is None:
            return
        operator = thread.operator
        if operator.step(self.node.current_status()):
            vehicle = self.spec.vehicle.id
            if not _wait(lambda: operator.outstanding(vehicle) == 0):
                raise ScenarioRunError("the simulated operator's answer never came back")

    def _pending(self, kind: m.OperatorRequestKind) -> m.OperatorRequest | None:
        """The unconfirmed VC request of ``kind`` the vehicle shows now, if any."""
        status = self.node.stack.vital_status()
        if status is None:
            return None
        for request in status.operator_requests:
            if request.kind is kind and not request.confirmed:
                return request
        return None

    def _route(self, action: Action) -> tuple[str | None, dict[str, Any]]:
        """The remote-driver route of an action and its body (None: no request to answer)."""
        confirmations = {
            "confirm_rearm": (m.OperatorRequestKind.EB_REARM, "eb-rearm"),
            "isolate_etcs": (m.OperatorRequestKind.ETCS_ISOLATION, "etcs-isolation"),
            "insert_etcs": (m.OperatorRequestKind.ETCS_INSERTION, "etcs-insertion"),
        }
        if action.do in confirmations:
            kind, route = confirmations[action.do]
            pending = self._pending(kind)
            return (None, {}) if pending is None else (route, {"number": pending.number})
        if action.do == "rd_target_speed":
            return "rd-target-speed", {"target_speed_kmh": action.speed_kmh}
        return action.do.replace("_", "-"), {}

    def _send_journey(self) -> tuple[bool, str | None]:
        """Store the journey from where the vehicle stands, and send it through the REST API
        while the vehicle runs (it answers at its next commands tick)."""
        journey = self.spec.journey
        assert journey is not None
        body = {
            "id": journey.id,
            "line_id": self.spec.line,
            "start_position_m": self.node.track_map.normalise(self.node.plant.position_m),
            "max_speed_mps": (
                None if journey.max_speed_kmh is None else journey.max_speed_kmh * MPS_PER_KMH
            ),
            "timing_points": [p.model_dump(mode="json") for p in journey.timing_points],
        }
        stored = self.rest.post("/api/v1/journeys", json=body, headers=self.headers)
        if stored.status_code != 201:
            return False, f"journey not stored ({stored.status_code}): {stored.text}"
        answer: list[Any] = []

        def send() -> None:
            answer.append(
                self.rest.post(
                    f"/api/v1/vehicles/{self.spec.vehicle.id}/journey-profile",
                    json={"journey_id": journey.id, "timeout_s": JOURNEY_TIMEOUT_S},
                    headers=self.headers,
                )
            )

        journeys_before = self.node.inputs_received[0]
        sender = threading.Thread(target=send, daemon=True)
        sender.start()
        # The profile reaches the node between slices; the next slice takes it and answers, so
        # the run does not depend on how fast the messages travel.
        received = _wait(lambda: self.node.inputs_received[0] > journeys_before, sender)
        if received:
            self._run(SLICE_S)
        sender.join(JOURNEY_TIMEOUT_S)
        if not answer:
            return False, "the trackside did not answer"
        response = answer[0]
        if response.status_code != 200:
            return False, f"{response.status_code}: {response.text}"
        reply = response.json()
        return bool(reply["accepted"]), reply.get("reason")

    # -- the outcome ---------------------------------------------------------------------------

    def _odometer_detection_s(self) -> float | None:
        """From the first odometer fault to the localisation reporting it, if both happened."""
        starts = [
            f.start_s
            for f in self.spec.faults
            if isinstance(f, OdometerFailure)
            or (isinstance(f, SensorDropout) and f.sensor == "odometer")
        ]
        lost = self.recorder.sensor_lost_s.get("odometer")
        if not starts or lost is None:
            return None
        return round(lost - min(starts), 3)

    def _outcome(self) -> RunOutcome:
        node, recorder = self.node, self.recorder
        stack, plant = node.stack, node.plant
        columns = recorder.arrays()
        low, high = plant.force_limits_n(0.0)
        counters = RunCounters(
            etcs_sb_count=stack.etcs.service_brake_interventions,
            etcs_eb_count=stack.etcs.emergency_brake_interventions,
            vc_eb_count=recorder.maxima.vc_eb_count,
            system_decay=stack.vital is not None and stack.vital.outputs.system_decay,
            traction_energy_j=plant.traction_energy_j,
            regen_energy_j=float(getattr(plant, "regen_energy_j", 0.0)),
            max_overspeed_mps=max(recorder.maxima.overspeed_mps, 0.0),
            nmpc_solve_times_s=stack.driving.nmpc.stats.solve_times_s,
            nmpc_failures=stack.driving.nmpc.stats.failures,
            nmpc_step_s=stack.driving.nmpc.config.step_s,
            force_range_n=high - low,
        )
        stops = [
            {
                "name": stop.name,
                "planned_arrival_s": stop.planned_arrival_s,
                "arrival_error_s": stop.arrival_s - stop.planned_arrival_s,
                "stop_error_m": stop.stop_error_m,
                "odometry_interval_m": stop.odometry_interval_m,
            }
            for stop in recorder.stops
        ]
        errors = columns["estimated_position_m"] - columns["position_m"]
        kpis = compute_kpis(
            columns,
            stops=stops,
            counters=counters,
            position_errors_m=errors,
            vc_interventions=recorder.vc_interventions,
        )
        kpis["odometry_interval_m"] = odometry_interval_kpi(
            columns,
            [stop.odometry_interval_m for stop in recorder.stops],
            outside_m=recorder.maxima.outside_interval_m,
        )
        kpis.update(
            scenario=self.spec.name,
            seed=self.seed,
            sim_time_s=node.clock.now_s,
            min_eoa_margin_m=_finite(recorder.maxima.eoa_margin_m),
            eoa_stops=[record.as_kpi() for record in recorder.eoa_stops],
            max_speed_over_cap_kmh=(
                None
                if recorder.cap_mps is None
                else max(recorder.maxima.over_cap_mps, 0.0) / MPS_PER_KMH
            ),
            min_obstacle_margin_m=_finite(recorder.maxima.obstacle_margin_m),
            sensor_lost_s=dict(recorder.sensor_lost_s),
            odometer_failure_detection_s=self._odometer_detection_s(),
            lockstep_barrier_misses=node.barrier_misses if self.options.fast else None,
            lockstep_report_retransmissions=(
                node.report_retransmissions if self.options.fast else None
            ),
            session_losses=node.session_client.counters.lost,
            sessions_established=node.session_client.counters.accepted,
            session_outages=self.session_outages,
            fallback_stops=sum(
                1
                for t in stack.controller.transitions
                if t.trigger is Trigger.FALLBACK_STOP_COMPLETED
            ),
            zenoh_link=None
            if self.link is None
            else {
                "cuts": self.link.proxy.stats().cuts,
                "connections_dropped": self.link.connections_dropped,
                "flaps_on_restore": self.link.flaps,
            },
        )
        kpis["wall_time_breakdown"] = _wall_time_breakdown(
            node.executive.stats, self.lockstep_wall_s
        )
        kpis["actions"] = [vars(item) for item in self.actions]
        expectations = check_expectations(kpis, self.spec.expect)
        expectations += [
            {"name": failure, "ok": False, "detail": failure} for failure in self.failures
        ]
        if self.spec.invariants is not None:
            expectations += invariant_expectations(self.spec, kpis)
        kpis["expectations"] = expectations
        kpis["passed"] = all(item["ok"] for item in expectations)
        return RunOutcome(_ordered_keys(kpis), columns)


def _wall_time_breakdown(stats: Mapping[str, TaskStats], lockstep_s: float) -> dict[str, Any]:
    """Where the wall time of the stepping went: each task's bodies, and the rest (the
    executive's own work and the slices' bookkeeping), largest first. A wall-clock field."""
    tasks = sorted(stats.items(), key=lambda item: item[1].exec_total_ns, reverse=True)
    in_tasks_s = sum(task.exec_total_ns for _, task in tasks) / 1e9
    return {
        "lockstep_s": round(lockstep_s, 3),
        "tasks": {
            name: {
                "releases": task.releases,
                "total_s": round(task.exec_total_ns / 1e9, 3),
                "mean_us": round(task.exec_mean_ns / 1e3, 1),
                "share": round(task.exec_total_ns / 1e9 / lockstep_s, 4) if lockstep_s else None,
            }
            for name, task in tasks
        },
        "executive_and_slices_s": round(lockstep_s - in_tasks_s, 3),
    }


def _wait(
    condition: Callable[[], bool],
    worker: threading.Thread | None = None,
    timeout_s: float = WAIT_S,
) -> bool:
    """Wait in wall time (the simulation stands still) until ``condition`` holds; False when
    it does not within ``timeout_s`` or ``worker`` ends first."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline or (worker is not None and not worker.is_alive()):
            return condition()
        time.sleep(0.0005)
    return True


def _fault_due(
    fault: Obstacle | ShortenedAuthority | TracksideRestart | TemporarySpeedRestriction,
    now_s: float,
    state: State,
) -> bool:
    """A one-shot fault's time has come and its condition (if any) holds."""
    if fault.at_s is not None and now_s < fault.at_s:
        return False
    condition = getattr(fault, "condition", None)
    return condition is None or bool(condition.holds(state))


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _forward_m(node: OnboardNode, from_m: float, to_m: float) -> float:
    """Along the line from ``from_m`` to ``to_m`` (round the ring if need be) [m]."""
    if node.track_map.line.ring:
        return (to_m - from_m) % node.track_map.length_m
    return to_m - from_m


def _sensor_settings(faults: tuple[Fault, ...], seed: int) -> SensorSettings:
    """The emulated sensors and their UDP link with the scenario's faults, seeded."""
    outages: dict[str, list[TimeWindow]] = {"imu": [], "odometer": [], "gps": []}
    stuck: list[TimeWindow] = []
    for fault in faults:
        if isinstance(fault, SensorDropout):
            outages[fault.sensor].append(TimeWindow(fault.start_s, fault.end_s))
        elif isinstance(fault, OdometerFailure):
            window = TimeWindow(fault.start_s, fault.end_s)
            (outages["odometer"] if fault.mode == "silent" else stuck).append(window)
    link = LinkFaults()
    udp = [fault for fault in faults if isinstance(fault, UdpLinkFault)]
    if len(udp) > 1:
        raise ScenarioRunError("one udp_link fault per scenario")
    if udp:
        fault = udp[0]
        link = LinkFaults(
            loss_rate=fault.loss,
            reorder_rate=fault.reorder,
            duplicate_rate=fault.duplicate,
            corrupt_rate=fault.corrupt,
            faults_from_s=max(fault.start_s, link.faults_from_s),
            faults_until_s=fault.end_s,
        )
    diameters = [fault.error for fault in faults if isinstance(fault, WheelDiameterError)]
    if len(diameters) > 1:
        raise ScenarioRunError("one wheel_diameter fault per scenario")
    missed = frozenset(
        group
        for fault in faults
        if isinstance(fault, BaliseMissed)
        for group in fault.balise_group_ids
    )
    return SensorSettings(
        seed=seed,
        link=link,
        wheel_diameter_error=diameters[0] if diameters else None,
        missed_balise_groups=missed,
        faults=SensorFaults(
            imu_outages=tuple(outages["imu"]),
            odometer_outages=tuple(outages["odometer"]),
            gps_outages=tuple(outages["gps"]),
            odometer_stuck_at_zero=tuple(stuck),
        ),
    )


def _vc_faults(faults: tuple[Fault, ...]) -> VcFaults:
    relay = [
        vc_hardware.RelayFault(start_s=f.start_s, end_s=f.end_s)
        for f in faults
        if isinstance(f, RelayFault)
    ]
    tachometer = [
        vc_hardware.TachometerFault(
            mode=vc_hardware.TachometerFaultMode(f.mode), start_s=f.start_s, end_s=f.end_s
        )
        for f in faults
        if isinstance(f, TachometerFault)
    ]
    return VcFaults(relay=relay, tachometer=tachometer)


def _condition(text: str) -> Callable[[State], bool]:
    from deploy.scenario.conditions import parse_condition

    return parse_condition(text).holds
