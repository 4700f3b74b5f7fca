"""``ato run`` of a multi-train scenario: several trains on one line in one lockstep run.

A scenario with ``[[trains]]`` puts other trains on its line beside its own vehicle (the lead
train). Each train is a whole onboard node of its own (its Zenoh session, its certificate, its
plant, its telemetry), and all of them talk to one trackside service whose RBC keeps them apart
(``[separation]``: ``trackside.separation``'s moving block). Each train's operator does its own
actions through that service, as a driver at the console holding several vehicles would.

The trains advance together, slice by slice (:data:`~deploy.scenario.runner.SLICE_S` of
simulated time each, in the scenario's order). Two waits keep a run independent of the
machine's speed, as the single-train run's barrier does:

- after a train's slice, until the trackside has acknowledged its last status report: the
  RBC has then taken every report of the slice, and sent what they change (an MA of the train
  behind);
- before a train's slice, until the train has every MA message the RBC has sent it.

After every slice the trains' true positions give the distance from each train's front end to
the rear end of the train ahead (on a ring, round the ring); the least of them over the run,
the headways at the stops and each train's verdict make ``kpis.json``'s ``fleet`` block. The
run's ``kpis.json`` is otherwise the lead train's; each other train's own report is written in a
directory named after its vehicle. Multi-train runs are lockstep only.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from collections import defaultdict
from collections.abc import Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

from deploy.pki import deployment_pki
from deploy.scenario.conditions import parse_condition
from deploy.scenario.kpi_model import (
    ExpectationResult,
    FleetKpis,
    Headway,
    Kpis,
    TrainSummary,
)
from deploy.scenario.line_source import resolve_line
from deploy.scenario.outcome import RunOutcome, build_outcome, judge
from deploy.scenario.run_context import (
    LINK_WAIT_S,
    RunContext,
    RunOptions,
    ScenarioRunError,
    wait_for,
)
from deploy.scenario.runner import (
    SLICE_S,
    TRACKSIDE,
    ProgressCallback,
    WholeStackRun,
    new_context,
    trackside_session,
)
from deploy.scenario.schema import ScenarioSpec
from deploy.scenario.telemetry import STANDSTILL_MPS, StopRecord
from deploy.scenario.trackside_harness import TracksideHarness
from deploy.scenario.vehicle_setup import onboard_settings
from onboard.node import OnboardNode
from onboard.runtime import SimClock
from protocol import TlsFiles, ZenohSettings, open_session
from protocol import messages as m
from trackdb import TrackMap

__all__ = ["FleetRun", "headways_at_stops", "nearest_ahead", "train_specs"]

SEED_MODULUS = 2**32


def train_specs(spec: ScenarioSpec) -> list[ScenarioSpec]:
    """One single-train scenario per train of ``spec``, the lead train first: the line, the
    duration, the end condition and the invariants are the run's; the faults stay the lead's."""
    lead = spec.model_copy(update={"trains": (), "separation": None})
    others = [
        lead.model_copy(
            update={
                "vehicle": train.vehicle,
                "operator": train.operator,
                "journey": train.journey,
                "actions": train.actions,
                "expect": train.expect,
                "faults": (),
            }
        )
        for train in spec.trains
    ]
    return [lead, *others]


@dataclasses.dataclass
class _Gap:
    """The least distance seen between two trains [m], when, and which."""

    distance_m: float = math.inf
    at_s: float | None = None
    behind: str = ""
    ahead: str = ""


class FleetRun:
    """The trains of one run, each a :class:`~deploy.scenario.runner.WholeStackRun` on the
    shared trackside, stepped together."""

    def __init__(self, spec: ScenarioSpec, trains: list[WholeStackRun]) -> None:
        self.spec = spec
        self.trains = trains
        self.ma_sent: dict[str, int] = defaultdict(int)
        """MA messages the RBC sent to each vehicle (revocations too)."""
        self.gap = _Gap()
        self.held_s: dict[str, float] = defaultdict(float)
        """How long each vehicle stood for an EoA short of its next stop [s]."""

    @classmethod
    @contextmanager
    def open(cls, spec: ScenarioSpec, options: RunOptions, seed: int) -> Iterator[FleetRun]:
        if not options.fast:
            raise ScenarioRunError("a multi-train run is lockstep only (--fast)")
        assert spec.separation is not None  # the schema asks for it with [[trains]]
        specs = train_specs(spec)
        ids = [train.vehicle.id for train in specs]
        track_map = TrackMap(resolve_line(spec, database_url=options.database_url))
        with ExitStack() as stack:
            scratch = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="ato-run-")))
            pki = (
                None
                if options.insecure
                else deployment_pki(scratch / "pki", vehicles=ids, tracksides=[TRACKSIDE])
            )
            trackside_zenoh, endpoint = trackside_session(
                stack, ids, None if pki is None else TlsFiles.of(pki, TRACKSIDE)
            )
            contexts = []
            for index, train in enumerate(specs):
                ctx = _train_context(
                    stack, train, index, options, seed, (scratch, pki, endpoint), track_map
                )
                contexts.append(ctx)
                stack.callback(ctx.node.close)
            lead = TracksideHarness(contexts[0], scratch, trackside_zenoh)
            lead.settings = lead.settings.model_copy(
                update={
                    "simulated_operators": tuple(
                        train.vehicle.id for train in specs if train.operator.simulated
                    ),
                    "separation_margin_m": spec.separation.margin_m,
                    "separation_extension_step_m": spec.separation.extension_step_m,
                    "journey_planning": spec.separation.plan_journeys,
                }
            )
            lead.start()
            stack.callback(lead.stop)
            harnesses = [lead, *(lead.for_train(ctx) for ctx in contexts[1:])]
            runs = [WholeStackRun(c, h) for c, h in zip(contexts, harnesses, strict=True)]
            run = cls(spec, runs)
            rbc = lead.rest.app.state.rbc  # type: ignore[attr-defined]
            rbc.add_listener(run._count_ma)
            yield run

    def _count_ma(self, message: m.MovementAuthorityMessage) -> None:
        self.ma_sent[message.vehicle_id] += 1

    # -- the loop ------------------------------------------------------------------------------

    def run(self, progress: ProgressCallback | None) -> RunOutcome:
        spec = self.spec
        end_when = None if spec.end_when is None else parse_condition(spec.end_when).holds
        for train in self.trains:
            if not _sees_trackside(train.ctx.node):
                raise ScenarioRunError(f"{train.ctx.spec.vehicle.id} never saw the trackside")
        lead = self.trains[0].ctx.node
        while lead.clock.now_s < spec.duration_s - 1e-9:
            if end_when is not None and all(end_when(t.state()) for t in self.trains):
                break
            step_s = min(SLICE_S, spec.duration_s - lead.clock.now_s)
            if not all(self._step(train, step_s) for train in self.trains):
                break
            self._measure(step_s)
            if progress is not None:
                progress(self.trains[0].progress_frame())
        for train in self.trains:
            train.operator.note_pending()
        return self._outcome()

    def _step(self, train: WholeStackRun, step_s: float) -> bool:
        """One slice of one train: its faults and operator, its MAs taken, then the slice;
        False when an action timed out (the run stops)."""
        ctx = train.ctx
        node = ctx.node
        state = train.state()
        train.faults.step(node.clock.now_s, state)
        if not train.operator.act(state, train.state):
            return False
        train.operator.answer_vc()
        train.operator.reengage(state)
        vehicle = ctx.spec.vehicle.id
        if not wait_for(lambda: node.inputs_received[1] >= self.ma_sent[vehicle]):
            raise ScenarioRunError(f"an MA of the RBC never reached {vehicle}")
        ctx.run_for(step_s)
        # The trackside has taken the slice's last report (and sent what it changes) once it
        # acknowledged it.
        wait_for(lambda: not node.barrier.outstanding)
        train.watch_session()
        return True

    def _measure(self, step_s: float) -> None:
        """The least distance from a train's front end to the rear end of the train ahead, and
        the time each train was held by its MA."""
        nodes = [train.ctx.node for train in self.trains]
        for node in nodes:
            if node.plant.speed_mps <= STANDSTILL_MPS and node.stack.driving.stopping_for_authority:
                self.held_s[node.settings.vehicle_id] += step_s
        track_map = nodes[0].track_map
        ring = track_map.line.ring
        fronts = [track_map.normalise(node.plant.position_m) for node in nodes]
        for index, node in enumerate(nodes):
            ahead = nearest_ahead(index, fronts, ring, track_map.length_m)
            if ahead is None:
                continue
            other, distance = ahead
            gap = distance - nodes[other].settings.train_length_m
            if gap < self.gap.distance_m:
                self.gap = _Gap(
                    gap,
                    round(node.clock.now_s, 6),
                    node.settings.vehicle_id,
                    nodes[other].settings.vehicle_id,
                )

    # -- the outcome ---------------------------------------------------------------------------

    def _outcome(self) -> RunOutcome:
        outcomes = [build_outcome(train.ctx, None) for train in self.trains]
        lead, lead_ctx = outcomes[0], self.trains[0].ctx
        fleet = _fleet_kpis(outcomes, [t.ctx for t in self.trains], self.gap, self.held_s)
        lead.kpis.fleet = fleet
        own = [ExpectationResult(name=text, ok=False, detail=text) for text in lead_ctx.failures]
        # The lead's own expectations may read the fleet block: judged again with it, and its
        # summary taken from that verdict.
        judge(lead.kpis, lead_ctx.spec, own)
        fleet.trains[0] = _summary(lead_ctx.spec.vehicle.id, lead.kpis, self.held_s)
        # The run's verdict takes in every train's and the separation's.
        others = [
            ExpectationResult(name=f"{summary.vehicle_id}: {name}", ok=False, detail=name)
            for summary in fleet.trains[1:]
            for name in summary.failed
        ]
        judge(lead.kpis, lead_ctx.spec, [*own, *others, _no_collision(fleet)])
        lead.trains = {
            train.ctx.spec.vehicle.id: outcome
            for train, outcome in zip(self.trains[1:], outcomes[1:], strict=True)
        }
        return lead


def _train_context(
    stack: ExitStack,
    spec: ScenarioSpec,
    index: int,
    options: RunOptions,
    seed: int,
    where: tuple[Path, Path | None, str],
    track_map: TrackMap,
) -> RunContext:
    """One train's node on its own Zenoh session to the trackside, and its run context: its
    own seed (the run's plus its index), its report in a directory of its own but the lead's.
    ``where``: the run's scratch directory, its PKI (None: insecure), the trackside's
    endpoint."""
    scratch, pki, endpoint = where
    vehicle = spec.vehicle.id
    train_seed = (seed + index) % SEED_MODULUS
    train_options = options
    if index > 0 and options.report_dir is not None:
        train_options = dataclasses.replace(options, report_dir=options.report_dir / vehicle)
    session = stack.enter_context(
        open_session(
            ZenohSettings(
                mode="peer",
                connect=(endpoint,),
                tls=None if pki is None else TlsFiles.of(pki, vehicle),
            )
        )
    )
    train_scratch = scratch / vehicle
    train_scratch.mkdir()
    node = OnboardNode(
        onboard_settings(spec, train_options, train_seed, train_scratch),
        session=session,
        clock=SimClock(),
        track_map=track_map,
    )
    return new_context(spec, train_options, train_seed, node)


def _sees_trackside(node: OnboardNode) -> bool:
    """Whether the node sees the trackside (waited for, in wall time)."""
    return wait_for(lambda: node.trackside_seen, timeout_s=LINK_WAIT_S)


def nearest_ahead(
    index: int, fronts: Sequence[float], ring: bool, length_m: float
) -> tuple[int, float] | None:
    """The train nearest ahead of train ``index`` and how far ahead its front end is [m]."""
    best: tuple[int, float] | None = None
    for other, front in enumerate(fronts):
        if other == index:
            continue
        distance = front - fronts[index]
        if ring:
            distance %= length_m
        elif distance <= 0.0:
            continue
        if best is None or distance < best[1]:
            best = (other, distance)
    return best


def _fleet_kpis(
    outcomes: Sequence[RunOutcome],
    contexts: Sequence[RunContext],
    gap: _Gap,
    held_s: Mapping[str, float],
) -> FleetKpis:
    headways = headways_at_stops([(ctx.spec.vehicle.id, ctx.recorder.stops) for ctx in contexts])
    return FleetKpis(
        trains=[
            _summary(ctx.spec.vehicle.id, outcome.kpis, held_s)
            for ctx, outcome in zip(contexts, outcomes, strict=True)
        ],
        min_distance_m=None if math.isinf(gap.distance_m) else round(gap.distance_m, 3),
        min_distance_at_s=gap.at_s,
        min_distance_between=[gap.behind, gap.ahead] if gap.at_s is not None else [],
        headways=headways,
        min_headway_s=min((h.headway_s for h in headways), default=None),
    )


def _summary(vehicle_id: str, kpis: Kpis, held_s: Mapping[str, float]) -> TrainSummary:
    return TrainSummary(
        vehicle_id=vehicle_id,
        passed=kpis.passed,
        held_s=round(held_s.get(vehicle_id, 0.0), 3),
        stops=len(kpis.stops),
        max_stop_error_m=max((abs(s.stop_error_m) for s in kpis.stops), default=None),
        max_arrival_delay_s=max((s.arrival_error_s for s in kpis.stops), default=None),
        eoa_stops=len(kpis.eoa_stops),
        max_overspeed_kmh=kpis.max_overspeed_kmh,
        etcs_sb_count=kpis.etcs_sb_count,
        etcs_eb_count=kpis.etcs_eb_count,
        vc_eb_count=kpis.vc_eb_count,
        failed=[item.name for item in kpis.expectations if not item.ok],
    )


def headways_at_stops(trains: Sequence[tuple[str, Sequence[StopRecord]]]) -> list[Headway]:
    """At each stop, the time between one train's arrival and the next's (on the run's clock).
    ``trains``: each train's vehicle id and the stops it served."""
    arrivals: dict[str, list[tuple[float, str]]] = defaultdict(list)
    for vehicle_id, stops in trains:
        for record in stops:
            arrivals[record.name].append((record.at_s, vehicle_id))
    headways = []
    for stop, seen in arrivals.items():
        seen.sort()
        for (first_s, first), (then_s, then) in zip(seen, seen[1:], strict=False):
            headways.append(
                Headway(stop=stop, ahead=first, behind=then, headway_s=round(then_s - first_s, 3))
            )
    return headways


def _no_collision(fleet: FleetKpis) -> ExpectationResult:
    """The separation's invariant, judged on the truth: no train ever reached the one ahead."""
    distance = fleet.min_distance_m
    ok = distance is None or distance > 0.0
    return ExpectationResult(
        name="no train reaches the train ahead (truth)",
        ok=ok,
        detail=f"least distance {distance} m",
    )
