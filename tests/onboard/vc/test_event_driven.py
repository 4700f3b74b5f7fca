"""Event-driven Tasks B and C (issue 24): skipping the quiet cycles changes nothing.

Over the whole catalogue, on one VC and on a 2-out-of-2 pair, and over random scenarios
(hypothesis: drivers, operators, faults of every kind, link delays off the 2 ms grid, timeouts
of any length), the VC that skips its quiet cycles and the one that runs every 2 ms show the
same outputs, statuses and valves at every 2 ms instant, and write the same datalog.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deploy.bench.vc_catalogue import CATALOGUE
from deploy.bench.vc_responder import (
    OperatorAction,
    OperatorActionKind,
    ResponderFault,
    ResponderFaultKind,
)
from deploy.bench.vc_runner import ScenarioResult, run_scenario
from deploy.bench.vc_scenarios import Fault, OutcomeClass, Scenario, SpeedTarget
from onboard.runtime import Executive, RealTimeClock, SimClock
from onboard.vc import (
    LinkDirection,
    LinkFault,
    LinkFaultKind,
    PipeFault,
    RelayFault,
    TachometerFault,
    TachometerFaultMode,
    VcConfig,
    VcHardware,
    VitalControl,
)
from onboard.vc.datalog import Datalog


def _both(scenario: Scenario, replicas: int, tmp: Path) -> tuple[ScenarioResult, ...]:
    results = []
    for event_driven in (False, True):
        path = tmp / f"{scenario.key}-{replicas}-{event_driven}.jsonl"
        with Datalog(path) as datalog:
            results.append(
                run_scenario(
                    scenario,
                    replicas=replicas,
                    event_driven=event_driven,
                    record_ticks=True,
                    datalog=datalog,
                )
            )
    return tuple(results)


def _assert_same(every_cycle: ScenarioResult, event_driven: ScenarioResult) -> None:
    assert len(event_driven.ticks) == len(every_cycle.ticks)
    for ours, theirs in zip(event_driven.ticks, every_cycle.ticks, strict=True):
        assert ours == theirs, f"first difference at {ours[0]} ns"
    assert event_driven.events == every_cycle.events
    assert event_driven.transitions == every_cycle.transitions
    assert event_driven.pair_events == every_cycle.pair_events
    assert event_driven.outcome is every_cycle.outcome
    assert every_cycle.skipped_cycles == 0


@pytest.mark.scenario
@pytest.mark.parametrize("replicas", [1, 2])
@pytest.mark.parametrize("key", [s.key for s in CATALOGUE])
def test_the_catalogue_runs_alike_event_driven_and_every_cycle(
    key: str, replicas: int, tmp_path: Path
) -> None:
    scenario = next(s for s in CATALOGUE if s.key == key)
    every_cycle, event_driven = _both(scenario, replicas, tmp_path)
    _assert_same(every_cycle, event_driven)
    logs = sorted(tmp_path.glob("*.jsonl"))
    assert logs[0].read_bytes() == logs[1].read_bytes()
    # Not vacuous: most cycles are quiet (two tasks a replica, one cycle per tick).
    assert event_driven.skipped_cycles > len(event_driven.ticks) * replicas


_TIME = st.floats(min_value=0.0, max_value=0.999, allow_nan=False)
"""A fraction of the run's duration."""


@st.composite
def _faults(draw: st.DrawFn, duration_s: float) -> tuple[Fault, ...]:
    faults: list[Fault] = []
    for _ in range(draw(st.integers(0, 3))):
        start_s = draw(_TIME) * duration_s
        end_s = start_s + draw(st.floats(0.001, duration_s))
        kind = draw(st.sampled_from(["link", "responder", "tachometer", "relay", "pipe"]))
        if kind == "link":
            faults.append(
                LinkFault(
                    direction=draw(st.sampled_from(LinkDirection)),
                    kind=draw(st.sampled_from(LinkFaultKind)),
                    start_s=start_s,
                    end_s=end_s,
                    delay_s=draw(st.floats(0.0, 0.06)),
                )
            )
        elif kind == "responder":
            faults.append(
                ResponderFault(
                    kind=draw(st.sampled_from(ResponderFaultKind)), start_s=start_s, end_s=end_s
                )
            )
        elif kind == "tachometer":
            mode = draw(st.sampled_from(TachometerFaultMode))
            faults.append(TachometerFault(mode=mode, start_s=start_s, end_s=end_s))
        elif kind == "relay":
            faults.append(RelayFault(start_s=start_s, end_s=end_s))
        else:
            faults.append(PipeFault(start_s=start_s, end_s=end_s))
    return tuple(faults)


@st.composite
def scenarios(draw: st.DrawFn) -> Scenario:
    """A random scenario: what is drawn is the VC's inputs, not an expected outcome."""
    duration_s = draw(st.floats(0.5, 4.0))
    config = VcConfig(
        vigilance_period_s=draw(st.floats(0.2, 3.0)),
        vigilance_timeout_s=draw(st.floats(0.05, 1.5)),
        rearm_timeout_s=draw(st.floats(0.05, 2.0)),
        relay_verification_timeout_s=draw(st.floats(0.005, 0.3)),
        tachometer_timeout_s=draw(st.floats(0.081, 0.3)),
        fused_speed_supervision=draw(st.booleans()),
        fused_speed_timeout_s=draw(st.floats(0.002, 0.05)),
    )
    return Scenario(
        key="random",
        title="random inputs",
        expected=OutcomeClass.NONE,
        duration_s=duration_s,
        driver=tuple(
            SpeedTarget(from_s=draw(_TIME) * duration_s, speed_kmh=draw(st.floats(0.0, 60.0)))
            for _ in range(draw(st.integers(0, 3)))
        ),
        operator=tuple(
            OperatorAction(
                at_s=draw(_TIME) * duration_s, kind=draw(st.sampled_from(OperatorActionKind))
            )
            for _ in range(draw(st.integers(0, 4)))
        ),
        auto_confirm_rearm=draw(st.booleans()),
        faults=draw(_faults(duration_s)),
        balise_telegrams=tuple(
            (draw(_TIME) * duration_s, draw(st.integers(0, 1000)))
            for _ in range(draw(st.integers(0, 3)))
        ),
        etcs_inserted_at_start=draw(st.booleans()),
        link_delay_s=draw(st.floats(0.0, 0.012)),
        full_eb_delay_s=draw(st.floats(0.05, 0.6)),
        config=config,
    )


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenario=scenarios(), replicas=st.sampled_from([1, 2]))
def test_random_inputs_run_alike_event_driven_and_every_cycle(
    scenario: Scenario, replicas: int
) -> None:
    every_cycle = run_scenario(scenario, replicas=replicas, event_driven=False, record_ticks=True)
    event_driven = run_scenario(scenario, replicas=replicas, event_driven=True, record_ticks=True)
    _assert_same(every_cycle, event_driven)


@pytest.mark.parametrize(
    ("clock", "skips"), [(SimClock(), True), (RealTimeClock(speed_factor=1000.0), False)]
)
def test_only_lockstep_skips_quiet_cycles_by_default(
    clock: SimClock | RealTimeClock, skips: bool
) -> None:
    vc = VitalControl(VcHardware.emulated())
    vc.register(Executive(clock))
    assert vc.task_b.quiet.enabled is skips
    assert vc.task_c.quiet.enabled is skips
