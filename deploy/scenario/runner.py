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

import math
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import zenoh

from deploy.bench.vc_runner import ScenarioResult
from deploy.bench.vc_runner import run_scenario as run_vc_scenario
from deploy.link_proxy import LinkProxy
from deploy.pki import deployment_pki
from deploy.ports import loopback_endpoint
from deploy.scenario.conditions import State
from deploy.scenario.fault_injector import FaultInjector
from deploy.scenario.kpi_model import EstimateError, Kpis, VcIntervention
from deploy.scenario.kpis import check_expectations
from deploy.scenario.line_source import resolve_line
from deploy.scenario.operator_script import OperatorScript
from deploy.scenario.outcome import RunOutcome, build_outcome
from deploy.scenario.report import render_report
from deploy.scenario.run_context import (
    LINK_WAIT_S,
    RunContext,
    RunOptions,
    ScenarioRunError,
    wait_for,
)
from deploy.scenario.schema import (
    AtoFailure,
    BaliseMissed,
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
from deploy.scenario.trackside_harness import TracksideHarness
from deploy.scenario.vehicle_setup import VC_DATALOG, onboard_settings
from deploy.scenario.zenoh_link import ZenohLinkFault
from onboard.node import OnboardNode
from onboard.runtime import RealTimeClock, SimClock
from protocol import TlsFiles, ZenohSettings, open_session
from protocol.access import access_control
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap

__all__ = [
    "SLICE_S",
    "VC_DATALOG",
    "Progress",
    "RunOptions",
    "RunOutcome",
    "ScenarioRunError",
    "WholeStackRun",
    "new_context",
    "run_scenario",
    "trackside_session",
    "write_report",
]

SLICE_S = 0.2
"""Simulated time between two looks of the operator [s] (one control period)."""
MIN_WALL_S = 1e-9
"""The least wall time a run is taken to last, for its real-time factor [s]."""
STANDSTILL_KMH = 0.036
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


@dataclass(frozen=True)
class Progress:
    """What the progress bar shows, once per slice."""

    sim_time_s: float
    duration_s: float
    speed_kmh: float
    etcs_mode: str
    ato_state: str
    sc_state: str


ProgressCallback = Callable[[Progress], None]
DEFAULT_OPTIONS = RunOptions()
TRACKSIDE = "ts1"
"""The run's trackside instance (``trackside.config.Settings.instance_id``'s default)."""


def _run_credentials(
    spec: ScenarioSpec, options: RunOptions, scratch: Path
) -> tuple[TlsFiles | None, TlsFiles | None]:
    """The trackside's and the onboard's TLS files, from a CA made for the run in ``scratch``
    (ECDSA keys: a few milliseconds); None for both when the run is insecure."""
    if options.insecure:
        return None, None
    pki = deployment_pki(scratch / "pki", vehicles=[spec.vehicle.id], tracksides=[TRACKSIDE])
    return TlsFiles.of(pki, TRACKSIDE), TlsFiles.of(pki, spec.vehicle.id)


def trackside_session(
    stack: ExitStack, vehicles: list[str], tls: TlsFiles | None
) -> tuple[zenoh.Session, str]:
    """The run's trackside Zenoh session, listening on a free loopback port (TLS, with the
    access control of ``vehicles`` and the trackside, unless ``tls`` is None: insecure), closed
    with ``stack``; and the endpoint the onboards connect to."""
    endpoint = loopback_endpoint()
    if tls is not None:
        endpoint = endpoint.replace("tcp/", "tls/", 1)
    session = stack.enter_context(
        open_session(
            ZenohSettings(
                mode="peer",
                connect=(),
                listen=(endpoint,),
                tls=tls,
                access_control=None
                if tls is None
                else access_control(vehicles=vehicles, tracksides=[TRACKSIDE]),
            )
        )
    )
    return session, endpoint


def run_scenario(
    spec: ScenarioSpec,
    options: RunOptions = DEFAULT_OPTIONS,
    *,
    progress: ProgressCallback | None = None,
) -> RunOutcome:
    """Run ``spec``; the outcome's ``kpis`` (a :class:`~deploy.scenario.kpi_model.Kpis`) follow
    CONTRACT.md §4."""
    seed = spec.seed if options.seed is None else options.seed
    started = time.perf_counter()
    if spec.vc is not None:
        outcome = _run_vc(spec, seed)
    elif spec.trains:
        from deploy.scenario.fleet import FleetRun  # it builds on this module

        with FleetRun.open(spec, options, seed) as fleet:
            outcome = fleet.run(progress)
    else:
        with WholeStackRun.open(spec, options, seed) as run:
            outcome = run.run(progress)
    wall_s = time.perf_counter() - started
    for kpis in (outcome.kpis, *(train.kpis for train in outcome.trains.values())):
        # The factor is a float of the contract: a run measured at 0 s (it never is) would be
        # inf. The trains of a multi-train run share its wall time.
        kpis.wall_time_s = wall_s
        kpis.real_time_factor = kpis.sim_time_s / max(wall_s, MIN_WALL_S)
        breakdown = kpis.wall_time_breakdown
        if breakdown is not None:
            breakdown.outside_lockstep_s = round(wall_s - breakdown.lockstep_s, 3)
    if options.report_dir is not None:
        write_report(outcome, options.report_dir)
        for vehicle_id, train in outcome.trains.items():
            write_report(train, options.report_dir / vehicle_id)
    return outcome


def write_report(outcome: RunOutcome, directory: Path) -> None:
    """``kpis.json``, and for whole-stack runs ``telemetry.npz`` and ``report.html``."""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "kpis.json").write_text(outcome.kpis.model_dump_json(indent=2), encoding="utf-8")
    if outcome.columns:
        np.savez_compressed(directory / "telemetry.npz", **outcome.columns)  # type: ignore[arg-type]
        (directory / "report.html").write_text(
            render_report(outcome.kpis, outcome.columns, outcome.optimum_profiles)
        )


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
    kpis = Kpis(
        scenario=spec.name,
        seed=seed,
        sim_time_s=scenario.duration_s,
        stops=[],
        eoa_stops=[],
        max_overspeed_kmh=0.0,
        etcs_sb_count=0,
        etcs_eb_count=0,
        vc_eb_count=sum(1 for e in result.events if e.kind.value == "eb_commanded"),
        system_decay=result.decay_s is not None,
        traction_energy_kwh=0.0,
        regen_energy_kwh=0.0,
        max_jerk_mps3=0.0,
        ad_speed_rms_kmh=None,
        rd_speed_rms_kmh=None,
        max_switch_du_frac=None,
        position_error_m=EstimateError(rms=0.0, max=0.0),
        nmpc_ms=None,
        nmpc_failures=0,
        nmpc_fallback_s=0.0,
        vc_interventions=_vc_interventions(result),
        vc_outcome=result.outcome.value,
        vc_expected_outcome=result.expected.value,
        vc_decay_reasons=list(result.decay_reasons),
        # The verdict is set below, the wall clock by run_scenario once the run is over.
        passed=False,
        expectations=[],
        wall_time_s=0.0,
        real_time_factor=0.0,
    )
    kpis.expectations = check_expectations(kpis, spec.expect)
    kpis.passed = all(item.ok for item in kpis.expectations)
    return RunOutcome(kpis)


def _vc_interventions(result: ScenarioResult) -> list[VcIntervention]:
    if result.eb_command_s is None:
        return []
    hazard = result.hazard_s
    return [
        VcIntervention(
            cause=result.key,
            hazard_to_eb_command_ms=None if hazard is None else _ms(result.eb_command_s - hazard),
            total_to_full_eb_ms=(
                None
                if hazard is None or result.full_eb_s is None
                else _ms(result.full_eb_s - hazard)
            ),
        )
    ]


# -- the whole stack ---------------------------------------------------------------------------


class WholeStackRun:
    """Trackside, onboard, faults and operator of one run, stepped slice by slice."""

    def __init__(
        self,
        ctx: RunContext,
        trackside: TracksideHarness,
        link: ZenohLinkFault | None = None,
    ) -> None:
        self.ctx = ctx
        self.trackside = trackside
        self.link = link
        self.faults = FaultInjector(ctx, trackside, link)
        self.operator = OperatorScript(ctx, trackside)
        self._session_up = False

    @classmethod
    @contextmanager
    def open(cls, spec: ScenarioSpec, options: RunOptions, seed: int) -> Iterator[WholeStackRun]:
        unwired = [f.kind for f in spec.faults if not isinstance(f, WHOLE_STACK_FAULTS)]
        if unwired:
            raise ScenarioRunError(f"faults not injected in whole-stack runs: {unwired}")
        if spec.vehicle.fidelity != "bogie" and any(
            isinstance(f, FrictionDrop) for f in spec.faults
        ):
            raise ScenarioRunError("friction_drop needs the bogie model (vehicle.fidelity)")
        track_map = TrackMap(resolve_line(spec, database_url=options.database_url))
        with ExitStack() as stack:
            scratch = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="ato-run-")))
            trackside_tls, onboard_tls = _run_credentials(spec, options, scratch)
            trackside_zenoh, endpoint = trackside_session(stack, [spec.vehicle.id], trackside_tls)
            # With a link fault the onboard reaches the trackside through a proxy that can cut
            # the link (closed after the sessions: the ExitStack unwinds in reverse).
            proxy = None
            connect = endpoint
            if any(isinstance(f, ZenohLinkLoss) for f in spec.faults):
                proxy = stack.enter_context(LinkProxy.to_endpoint(endpoint))
                connect = ZenohLinkFault.connect_endpoint(proxy)
            onboard_zenoh = stack.enter_context(
                open_session(ZenohSettings(mode="peer", connect=(connect,), tls=onboard_tls))
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
            node = OnboardNode(
                onboard_settings(spec, options, seed, scratch),
                session=onboard_zenoh,
                clock=SimClock() if options.fast else RealTimeClock(options.speed),
                track_map=track_map,
            )
            stack.callback(node.close)
            ctx = new_context(spec, options, seed, node)
            trackside = TracksideHarness(ctx, scratch, trackside_zenoh)
            trackside.start()
            stack.callback(trackside.stop)
            yield cls(ctx, trackside, link)

    # -- the loop ------------------------------------------------------------------------------

    def run(self, progress: ProgressCallback | None) -> RunOutcome:
        ctx = self.ctx
        spec, node = ctx.spec, ctx.node
        end_when = None if spec.end_when is None else _condition(spec.end_when)
        # The first handshake is due at the first tick: it is made once the onboard sees the
        # trackside, however long the two sessions take to meet in wall time.
        if not wait_for(lambda: node.trackside_seen, timeout_s=LINK_WAIT_S):
            raise ScenarioRunError("the onboard never saw the trackside")
        while node.clock.now_s < spec.duration_s - 1e-9:
            state = self.state()
            if end_when is not None and end_when(state):
                break
            self.faults.step(node.clock.now_s, state)
            if not self.operator.act(state, self.state):
                break
            self.operator.answer_vc()
            self.operator.reengage(state)
            ctx.run_for(min(SLICE_S, spec.duration_s - node.clock.now_s))
            self.watch_session()
            if progress is not None:
                progress(self.progress_frame())
        self.operator.note_pending()
        return build_outcome(ctx, self.link)

    def watch_session(self) -> None:
        """Note each loss of the established session and its re-establishment (to the slice)."""
        node, outages = self.ctx.node, self.ctx.session_outages
        established = node.session_client.established
        if established == self._session_up:
            return
        self._session_up = established
        now_s = round(node.clock.now_s, 6)
        if not established:
            outages.append({"lost_s": now_s, "reestablished_s": None, "duration_s": None})
        elif outages and outages[-1]["reestablished_s"] is None:
            outage = outages[-1]
            lost_s = outage["lost_s"]
            assert lost_s is not None
            outage.update(reestablished_s=now_s, duration_s=round(now_s - lost_s, 6))

    def progress_frame(self) -> Progress:
        node = self.ctx.node
        stack = node.stack
        return Progress(
            sim_time_s=node.clock.now_s,
            duration_s=self.ctx.spec.duration_s,
            speed_kmh=node.plant.speed_mps / MPS_PER_KMH,
            etcs_mode=stack.etcs.mode.value,
            ato_state=stack.ato_state.value,
            sc_state=stack.driving.state.value,
        )

    def state(self) -> State:
        """The fields of ``deploy.scenario.conditions`` now."""
        node = self.ctx.node
        stack, plant = node.stack, node.plant
        vital = stack.vital
        driving = stack.driving
        standstill = plant.speed_mps / MPS_PER_KMH < STANDSTILL_KMH
        next_stop = None if driving.journey is None else driving.next_stop(plant.position_m)
        # Ended once the train stands past its last stop and the ADF believes it stands at it
        # (on its estimate, which may come to standstill a moment after the truth): the stop
        # is then recorded (telemetry, ``_note_stop``) before the run ends.
        ended = (
            driving.journey is not None
            and next_stop is None
            and standstill
            and driving.stopped_at(stack.position_m, stack.speed_mps) is not None
        )
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


def new_context(
    spec: ScenarioSpec, options: RunOptions, seed: int, node: OnboardNode
) -> RunContext:
    """The run's shared state, with a telemetry recorder on the node."""
    recorder = TelemetryRecorder(node)
    recorder.register()
    if spec.journey is not None and spec.journey.max_speed_kmh is not None:
        recorder.cap_mps = spec.journey.max_speed_kmh * MPS_PER_KMH
    recorder.hazards_s.extend(
        fault.start_s for fault in spec.faults if isinstance(fault, RelayFault | TachometerFault)
    )
    return RunContext(
        spec=spec,
        options=options,
        seed=seed,
        node=node,
        recorder=recorder,
        operator_present=spec.operator.simulated,
    )


def _condition(text: str) -> Callable[[State], bool]:
    from deploy.scenario.conditions import parse_condition

    return parse_condition(text).holds
