"""Run a VC scenario in lockstep and measure it (seed 004 §4.2; DOMAIN.md §6, §7.2).

:func:`run_scenario` builds the emulated hardware, a :class:`VitalControl`, an
:class:`AtoObResponder` and a small kinematic train on a :class:`~onboard.runtime.SimClock` and
an :class:`~onboard.runtime.Executive`, runs the scenario for its duration and returns a
:class:`ScenarioResult`: the outcome class, and in simulated time

- hazard → EB command (valves de-energised) and hazard → full EB (pipe vented, 450 ms later);
- evidence → EB command: from the moment the evidence reached the VC (a response's arrival, a
  tachometer frame's arrival, a deadline's expiry) to the command, the VC's own elaboration time,
  the figure the seeds measure (A 10 ms, B 2 ms, E 12 ms, N 2 ms);
- hazard → System Decay and evidence → System Decay.

Tick order (priorities): the surroundings (train, odometry board, BTM) first, then VC Tasks B,
C, A, then the ATO-OB double, all every 2 ms but A (40 ms).

The train (ground truth, seen by the VC only through the tachometer board) follows the remote
driver's target speed under a traction and a service-brake limit, and the EB's effort grows as
the brake pipe vents. Its numbers are the URV's (``onboard.etcs.URV_TRAIN_DATA``) where they
exist.
"""

from __future__ import annotations

import math
import random
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

from deploy.bench.vc_responder import AtoObResponder, ResponderFault
from deploy.bench.vc_scenarios import (
    SEED_HAZARDOUS_COUNTS,
    SEED_SCENARIO_COUNT,
    HazardKind,
    OutcomeClass,
    Scenario,
    ScenarioError,
)
from onboard.etcs.balises import TelegramHeader
from onboard.etcs.values import URV_TRAIN_DATA
from onboard.runtime import Executive, SimClock
from onboard.runtime.clock import NS_PER_S
from onboard.vc.datalog import Datalog, DatalogRecorder
from onboard.vc.fsm import FsmCoverage, FsmTransition, transition_coverage
from onboard.vc.hardware import (
    EmergencyBrakeValves,
    PipeFault,
    RelayFault,
    TachometerBoard,
    TachometerFault,
)
from onboard.vc.ipc import Delivery, VcEvent, VcEventKind
from onboard.vc.link import LinkFault
from onboard.vc.module import TASK_B_PRIORITY, VcHardware, VitalControl
from onboard.vc.redundancy import PairEvent, TwoOutOfTwo
from protocol.units import MPS_PER_KMH

__all__ = [
    "ATO_OB_PRIORITY",
    "SEED_TIMINGS_MS",
    "STEP_S",
    "SURROUNDINGS_PRIORITY",
    "ScenarioResult",
    "TrainMotion",
    "count_by_class",
    "format_report",
    "run_catalogue",
    "run_scenario",
]

SURROUNDINGS_PRIORITY = TASK_B_PRIORITY + 10
FUSION_LAG_S = 0.010
"""The sensor-fusion speed lags the truth by one IMU period (100 Hz) [s]."""
FUSION_SPEED_SIGMA_MPS = 0.05
"""⚠ Its noise: about the sensor-fusion issue's 0.2 km/h RMS speed error [m/s]."""
FUSION_CORRELATION_S = 1.0
"""⚠ A Kalman filter's speed error drifts slowly: a first-order Gauss–Markov error [s]."""
EARLY_OVERSPEED_S = 0.5
ATO_OB_PRIORITY = 0
RECORDER_PRIORITY = ATO_OB_PRIORITY - 10
"""What the VC shows at a tick is read after every task of the tick."""
STEP_S = 0.002
MOVING_MPS = 0.01
"""Above this true speed the train is moving."""

SEED_TIMINGS_MS: dict[str, str] = {
    "A": "10 (+80 exchange +450 = 540)",
    "B": "2",
    "E": "12",
    "N": "2",
    "L": "6 (+80 data +450 = 536)",
    "M": "6 (+80 data +450 = 536)",
    "F": "2 (decay)",
    "G": "2 (decay)",
}
"""The seeds' figures by letter, VC elaboration first [ms] (seed 004 §4.2, seed 001 §IV.C)."""


class TrainMotion:
    """The train's ground truth: a point mass following the remote driver's target speed.

    Accelerations in m/s². Traction only with the EB released (valves energised, pipe charged);
    the EB's deceleration is its full value times the pipe's pressure drop.
    """

    def __init__(
        self,
        *,
        traction_mps2: float = 1.0,
        service_brake_mps2: float = URV_TRAIN_DATA.a_brake_service_mps2,
        emergency_brake_mps2: float = URV_TRAIN_DATA.a_brake_emergency_mps2,
        gain_per_s: float = 1.0,
    ) -> None:
        self.traction_mps2 = traction_mps2
        self.service_brake_mps2 = service_brake_mps2
        self.emergency_brake_mps2 = emergency_brake_mps2
        self.gain_per_s = gain_per_s
        self.speed_mps = 0.0
        self.distance_m = 0.0
        self.time_s = 0.0

    def advance(
        self, now_s: float, *, target_mps: float, eb_effort: float, traction_available: bool
    ) -> None:
        dt_s = now_s - self.time_s
        self.time_s = now_s
        if dt_s <= 0:
            return
        demand = self.gain_per_s * (target_mps - self.speed_mps)
        demand = min(self.traction_mps2, max(-self.service_brake_mps2, demand))
        if not traction_available:
            demand = min(demand, 0.0)
        acceleration = demand - eb_effort * self.emergency_brake_mps2
        speed = max(0.0, self.speed_mps + acceleration * dt_s)
        self.distance_m += (self.speed_mps + speed) / 2 * dt_s
        self.speed_mps = speed


class _Surroundings:
    """Everything around the VC in a scenario: the train, the odometry board, the BTM and, with
    ``fused_speed_supervision``, the sensor-fusion speed. One board feeds every replica."""

    def __init__(
        self,
        scenario: Scenario,
        boards: Sequence[VcHardware],
        valves: EmergencyBrakeValves,
        *,
        fusion_seed: int = 0,
    ) -> None:
        self.scenario = scenario
        self.boards = tuple(boards)
        self.valves = valves
        self.relay = self.boards[0].relay
        self.train = TrainMotion()
        config = scenario.config
        self.board = TachometerBoard(
            metres_per_pulse=config.metres_per_pulse,
            period_s=config.tachometer_period_s,
            faults=[f for f in scenario.faults if isinstance(f, TachometerFault)],
        )
        self._targets = sorted(scenario.driver, key=lambda t: t.from_s)
        self._telegrams = sorted(scenario.balise_telegrams)
        self._fusion_noise = random.Random(fusion_seed)
        self._fusion_error_mps = 0.0
        self.speeds_mps: list[float] = []
        """The true speed at each 2 ms step."""
        self.overspeed_s: float | None = None

    def target_mps(self, now_s: float) -> float:
        target = 0.0
        for item in self._targets:
            if item.from_s <= now_s:
                target = item.speed_kmh * MPS_PER_KMH
        return target

    def step_ns(self, release_ns: int) -> None:
        now_s = release_ns / NS_PER_S
        valves, relay = self.valves, self.relay
        before_mps = self.train.speed_mps
        self.train.advance(
            now_s,
            target_mps=self.target_mps(now_s),
            eb_effort=valves.brake_effort(now_s),
            traction_available=valves.eb_released(now_s),
        )
        speed = self.train.speed_mps
        self.speeds_mps.append(speed)
        limit = self.scenario.config.speed_limit_etcs_isolated_mps
        if self.overspeed_s is None and speed > limit >= before_mps and not relay.inserted(now_s):
            self.overspeed_s = now_s - STEP_S * (speed - limit) / (speed - before_mps)
        frame = self.board.poll(now_s, self.train.distance_m)
        fused = self._fused_speed_mps() if self.scenario.config.fused_speed_supervision else None
        while self._telegrams and self._telegrams[0][0] <= now_s:
            _, group = self._telegrams.pop(0)
            header = TelegramHeader(nid_bg=group, q_link=1)
            for hardware in self.boards:
                hardware.balise_telegrams.put(Delivery(header, now_s))
        for hardware in self.boards:
            if frame is not None:
                hardware.tachometer_frames.put(Delivery(frame, now_s))
            if fused is not None:
                hardware.fused_speeds.put(Delivery(fused, now_s))

    def _fused_speed_mps(self) -> float:
        """The sensor fusion's speed: the true speed one IMU period ago, with its error."""
        lag = round(FUSION_LAG_S / STEP_S)
        truth = self.speeds_mps[max(0, len(self.speeds_mps) - 1 - lag)]
        keep = math.exp(-STEP_S / FUSION_CORRELATION_S)
        innovation = self._fusion_noise.gauss(0.0, FUSION_SPEED_SIGMA_MPS)
        self._fusion_error_mps = keep * self._fusion_error_mps + math.sqrt(1 - keep**2) * innovation
        return truth + self._fusion_error_mps

    def speed_at(self, time_s: float) -> float:
        index = min(len(self.speeds_mps) - 1, max(0, round(time_s / STEP_S)))
        return self.speeds_mps[index] if self.speeds_mps else 0.0


@dataclass(frozen=True, kw_only=True)
class ScenarioResult:
    """What a scenario run did, in simulated time [s]."""

    key: str
    title: str
    expected: OutcomeClass
    outcome: OutcomeClass
    hazard_s: float | None
    evidence_s: float | None
    """When the first evidence after the hazard reached the VC."""
    eb_command_s: float | None
    """The first EB command (valves de-energised) at or after the hazard."""
    full_eb_s: float | None
    decay_s: float | None
    decay_evidence_s: float | None
    """When the evidence behind System Decay reached the VC."""
    rearmed_s: float | None
    """The last EB rearm verified after the first EB command."""
    speed_at_intervention_kmh: float | None
    decay_reasons: tuple[str, ...]
    events: tuple[VcEvent, ...]
    transitions: tuple[FsmTransition, ...]
    pair_events: tuple[PairEvent, ...] = ()
    """2-out-of-2 only: the pair's events (replica EB, disagreement, watchdog)."""
    ticks: tuple[tuple[object, ...], ...] = ()
    """With ``record_ticks``: at every 2 ms instant, after every task, each replica's outputs
    and its Tasks B and C's statuses, and the vehicle's valves."""
    skipped_cycles: int = 0
    """Cycles of Tasks B and C (all replicas) skipped as quiet (event-driven runs)."""

    @property
    def passed(self) -> bool:
        return self.outcome is self.expected

    def _since(self, start: float | None, end: float | None) -> float | None:
        return None if start is None or end is None else end - start

    @property
    def hazard_to_eb_command_s(self) -> float | None:
        return self._since(self.hazard_s, self.eb_command_s)

    @property
    def hazard_to_full_eb_s(self) -> float | None:
        return self._since(self.hazard_s, self.full_eb_s)

    @property
    def evidence_to_eb_command_s(self) -> float | None:
        return self._since(self.evidence_s, self.eb_command_s)

    @property
    def hazard_to_decay_s(self) -> float | None:
        return self._since(self.hazard_s, self.decay_s)

    @property
    def evidence_to_decay_s(self) -> float | None:
        return self._since(self.decay_evidence_s, self.decay_s)


def _crossing_ahead_s(scenario: Scenario, surroundings: _Surroundings) -> float | None:
    """When the true speed would have crossed the limit, had the EB not come first: the first
    EB command on an accelerating train, extrapolated at its acceleration."""
    limit = scenario.config.speed_limit_etcs_isolated_mps
    for command in surroundings.valves.commands:
        index = round(command.time_s / STEP_S)
        if command.energised or index < 2 or index >= len(surroundings.speeds_mps):
            continue
        speeds = surroundings.speeds_mps
        acceleration = (speeds[index - 1] - speeds[index - 2]) / STEP_S
        if acceleration > 0 and speeds[index] > limit - 1.0:
            return command.time_s + (limit - speeds[index]) / acceleration
    return None


def _hazard_s(scenario: Scenario, vc: VitalControl, surroundings: _Surroundings) -> float | None:
    hazard = scenario.hazard
    if hazard is None:
        return None
    if hazard.kind is HazardKind.AT:
        return hazard.at_s
    if hazard.kind is HazardKind.OVERSPEED:
        return surroundings.overspeed_s or _crossing_ahead_s(scenario, surroundings)
    if hazard.kind is HazardKind.RELAY_COMMAND:
        commands = vc.hardware.relay.commands
        return commands[0][0] if commands else None
    rearms = [
        c.time_s for c in surroundings.valves.commands if c.energised and c.time_s >= hazard.at_s
    ]
    return rearms[0] if rearms else None


def _first(events: Iterable[VcEvent], kinds: set[VcEventKind], after_s: float) -> VcEvent | None:
    return next((e for e in events if e.kind in kinds and e.time_s >= after_s), None)


def _classify(
    eb_moving: bool, decay_s: float | None, eb_commands: Sequence[float], moving_at_decay: bool
) -> OutcomeClass:
    if decay_s is not None:
        if eb_moving or moving_at_decay:
            return OutcomeClass.EB_THEN_DECAY
        return OutcomeClass.DECAY_AT_STANDSTILL
    return OutcomeClass.EB_SAFE_RECOVERY if eb_commands else OutcomeClass.NONE


def _hardware(scenario: Scenario) -> VcHardware:
    faults = scenario.faults
    return VcHardware.emulated(
        link_delay_s=scenario.link_delay_s,
        link_faults=[f for f in faults if isinstance(f, LinkFault)],
        venting_s=scenario.full_eb_delay_s,
        pipe_faults=[f for f in faults if isinstance(f, PipeFault)],
        etcs_inserted=scenario.etcs_inserted_at_start,
        relay_faults=[f for f in faults if isinstance(f, RelayFault)],
    )


def run_scenario(
    scenario: Scenario,
    *,
    replicas: int = 1,
    seed: int = 0,
    event_driven: bool | None = None,
    record_ticks: bool = False,
    datalog: Datalog | None = None,
) -> ScenarioResult:
    """Run ``scenario`` in lockstep for its duration, on one VC or on two in 2-out-of-2
    (``replicas=2``: each replica with its own link and ATO-OB answering it, the same
    inputs, the vehicle's valves the pair's); measure and classify it. ``seed`` drives the
    sensor-fusion speed's error (``fused_speed_supervision`` only). ``event_driven``: Tasks B
    and C skip their quiet cycles (None: as in any lockstep run, yes); ``record_ticks`` keeps
    what the VC shows at every 2 ms instant, ``datalog`` records its notifications there."""
    if replicas not in (1, 2):
        raise ScenarioError(f"one VC or a 2-out-of-2 pair, not {replicas}")
    boards = [_hardware(scenario) for _ in range(replicas)]
    vcs = [VitalControl(hardware, config=scenario.config) for hardware in boards]
    executive = Executive(SimClock())
    pair = _register_vcs(scenario, vcs, executive, event_driven=event_driven)
    surroundings = _Surroundings(
        scenario, boards, pair.valves if pair else boards[0].valves, fusion_seed=seed
    )
    executive.add_task(
        "surroundings", surroundings.step_ns, period_s=STEP_S, priority=SURROUNDINGS_PRIORITY
    )
    _add_responders(scenario, boards, executive)
    ticks: list[tuple[object, ...]] = []
    if record_ticks:
        executive.add_task(
            "ticks",
            lambda release_ns: ticks.append(_tick(vcs, surroundings.valves, release_ns)),
            period_s=STEP_S,
            priority=RECORDER_PRIORITY,
        )
    if datalog is not None:
        DatalogRecorder(datalog, vcs[0], pair=pair).register(executive, period_s=STEP_S)
    executive.run_until(round(scenario.duration_s * NS_PER_S))
    result = _result(scenario, vcs[0], surroundings, pair=pair)
    skipped = sum(vc.task_b.quiet.skipped + vc.task_c.quiet.skipped for vc in vcs)
    return replace(result, ticks=tuple(ticks), skipped_cycles=skipped)


def _register_vcs(
    scenario: Scenario,
    vcs: Sequence[VitalControl],
    executive: Executive,
    *,
    event_driven: bool | None,
) -> TwoOutOfTwo | None:
    """The one VC's tasks on the executive, or the 2-out-of-2 pair's (returned)."""
    if len(vcs) == 1:
        vcs[0].register(executive, event_driven=event_driven)
        return None
    pair = TwoOutOfTwo(
        (vcs[0], vcs[1]),
        valves=EmergencyBrakeValves(
            venting_s=scenario.full_eb_delay_s,
            faults=[f for f in scenario.faults if isinstance(f, PipeFault)],
        ),
    )
    pair.register(executive, event_driven=event_driven)
    return pair


def _add_responders(scenario: Scenario, boards: Sequence[VcHardware], executive: Executive) -> None:
    """An ATO-OB answering each board's VC, with the scenario's operator and faults."""
    for index, hardware in enumerate(boards):
        responder = AtoObResponder(
            hardware.request_link,
            hardware.response_link,
            sequence_modulo=scenario.config.sequence_modulo,
            auto_confirm_rearm=scenario.auto_confirm_rearm,
            actions=scenario.operator,
            faults=[f for f in scenario.faults if isinstance(f, ResponderFault)],
        )
        executive.add_task(
            f"ato_ob{index}", responder.step_ns, period_s=STEP_S, priority=ATO_OB_PRIORITY
        )


def _tick(
    vcs: Sequence[VitalControl], valves: EmergencyBrakeValves, release_ns: int
) -> tuple[object, ...]:
    now_s = release_ns / NS_PER_S
    shown: list[object] = [release_ns, valves.energised, valves.pressure_fraction(now_s)]
    for vc in vcs:
        shown += [vc.outputs, vc.task_b.status.read(), vc.task_c.status.read()]
    return tuple(shown)


def _result(
    scenario: Scenario,
    vc: VitalControl,
    surroundings: _Surroundings,
    *,
    pair: TwoOutOfTwo | None = None,
) -> ScenarioResult:
    events = vc.events
    valves = surroundings.valves
    eb_commands = [c for c in valves.commands if not c.energised]
    eb_moving = any(surroundings.speed_at(c.time_s) > MOVING_MPS for c in eb_commands)
    hazard_s = _hazard_s(scenario, vc, surroundings)
    after_s = hazard_s if hazard_s is not None else math.inf
    if hazard_s is not None and scenario.hazard and scenario.hazard.kind is HazardKind.OVERSPEED:
        # The fused speed's error may take it over the limit before the truth: an EB shortly
        # before the true crossing counts, with a negative time.
        after_s -= EARLY_OVERSPEED_S
    evidence = _first(events, {VcEventKind.EB_CONDITION, VcEventKind.SYSTEM_DECAY}, after_s)
    command = next((c for c in eb_commands if c.time_s >= after_s), None)
    decay = _first(events, {VcEventKind.SYSTEM_DECAY}, 0.0)
    moving_at_decay = decay is not None and surroundings.speed_at(decay.time_s) > MOVING_MPS
    rearms = [
        e.time_s
        for e in events
        if e.kind is VcEventKind.EB_REARMED and eb_commands and e.time_s > eb_commands[0].time_s
    ]
    intervention_s = command.time_s if command else (decay.time_s if decay else None)
    return ScenarioResult(
        key=scenario.key,
        title=scenario.title,
        expected=scenario.expected,
        outcome=_classify(
            eb_moving,
            decay.time_s if decay else None,
            [c.time_s for c in eb_commands],
            moving_at_decay,
        ),
        hazard_s=hazard_s,
        evidence_s=evidence.evidence_s if evidence else None,
        eb_command_s=command.time_s if command else None,
        full_eb_s=valves.full_emergency_brake_s(command) if command else None,
        decay_s=decay.time_s if decay else None,
        decay_evidence_s=decay.evidence_s if decay else None,
        rearmed_s=rearms[-1] if rearms else None,
        speed_at_intervention_kmh=(
            surroundings.speed_at(intervention_s) / MPS_PER_KMH
            if intervention_s is not None
            else None
        ),
        decay_reasons=vc.outputs.decay_reasons,
        events=tuple(events),
        transitions=tuple(vc.transitions),
        pair_events=tuple(pair.events) if pair is not None else (),
    )


def run_catalogue(scenarios: Iterable[Scenario]) -> tuple[ScenarioResult, ...]:
    """Run each scenario; the results in the same order."""
    return tuple(run_scenario(s) for s in scenarios)


def count_by_class(results: Iterable[ScenarioResult]) -> dict[OutcomeClass, int]:
    counts = dict.fromkeys(OutcomeClass, 0)
    for result in results:
        counts[result.outcome] += 1
    return counts


def _ms(value: float | None) -> str:
    return "—" if value is None else f"{value * 1000:.0f}"


def format_report(results: Sequence[ScenarioResult]) -> str:
    """Counts by class beside the seeds', the timing table, and the FSMs' coverage, as text."""
    counts = count_by_class(results)
    hazardous = sum(counts[c] for c in SEED_HAZARDOUS_COUNTS)
    lines = [
        f"VC scenario catalogue: {len(results)} scenarios (seeds: {SEED_SCENARIO_COUNT}), "
        f"{hazardous} hazardous (seeds: {sum(SEED_HAZARDOUS_COUNTS.values())})",
    ]
    for outcome in OutcomeClass:
        seed = SEED_HAZARDOUS_COUNTS.get(outcome, SEED_SCENARIO_COUNT - 23)
        lines.append(f"  {outcome.value:<22} {counts[outcome]:>3}   seeds {seed:>3}")
    lines.append("")
    lines.append(
        f"{'scenario':<26}{'class':<21}{'v km/h':>7}{'haz→EB':>8}{'evid→EB':>8}"
        f"{'haz→full':>9}{'haz→decay':>10}{'evid→decay':>11}  seeds [ms]"
    )
    for result in results:
        if result.outcome is OutcomeClass.NONE:
            continue
        speed = result.speed_at_intervention_kmh
        braking = result.outcome is not OutcomeClass.DECAY_AT_STANDSTILL
        lines.append(
            f"{result.key:<26}{result.outcome.value:<21}"
            f"{'—' if speed is None else f'{speed:.1f}':>7}"
            f"{_ms(result.hazard_to_eb_command_s if braking else None):>8}"
            f"{_ms(result.evidence_to_eb_command_s if braking else None):>8}"
            f"{_ms(result.hazard_to_full_eb_s if braking else None):>9}"
            f"{_ms(result.hazard_to_decay_s):>10}{_ms(result.evidence_to_decay_s):>11}"
            f"  {SEED_TIMINGS_MS.get(result.key, '')}"
        )
    lines.append("")
    coverage = transition_coverage(t for r in results for t in r.transitions)
    lines.extend(_coverage_line(item) for item in coverage.values())
    return "\n".join(lines)


def _coverage_line(item: FsmCoverage) -> str:
    missing = ", ".join(item.rows_missing + item.pairs_missing) or "none missing"
    return (
        f"FSM {item.fsm.value:<8} rows {item.rows_covered:.0%} of {item.rows_total}, "
        f"(row, source) pairs {item.pairs_covered:.0%} of {item.pairs_total}: {missing}"
    )
