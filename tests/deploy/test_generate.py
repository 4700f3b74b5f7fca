"""The scenario generator: determinism, the space file, the invariants, the shrinker, and
end to end a failing generated scenario shrunk by real runs and re-run with `ato run FILE`."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from deploy.cli import app
from deploy.scenario import load_scenario
from deploy.scenario.console import run_from_cli
from deploy.scenario.generate import draw, generate, plain_lspb_time_s, render
from deploy.scenario.generated import run_generated
from deploy.scenario.invariants import INVARIANTS, Violation, judge
from deploy.scenario.schema import (
    Fault,
    InvariantSettings,
    OdometerFailure,
    ScenarioSpec,
    SensorDropout,
    ShortenedAuthority,
)
from deploy.scenario.shrink import shrink
from deploy.scenario.space import DEFAULT_SPACE, GeneratorSpace, SpaceFileError, load_space
from tests.deploy.kpi_samples import sample_kpis

SMALL_SPACE = """
name = "small"
line = "bologna-ring"
legs = [1, 1]
skip_platform = 0.0
cap_kmh = [30.0, 60.0]
slack = [0.1, 0.3]
dwell_s = [10.0, 20.0]
reaction_s = [0.5, 2.0]
duration_margin_s = 120.0

[tsr]
count = [0, 0]

[ma]
count = [0, 0]

[faults]
count = [1, 1]

[faults.kinds.sensor_dropout]
window_s = [5.0, 20.0]
"""


def _space(tmp_path: Path, text: str = SMALL_SPACE, **invariants: Any) -> GeneratorSpace:
    if invariants:
        text += "\n[invariants]\n" + "".join(f"{k} = {v!r}\n" for k, v in invariants.items())
    path = tmp_path / "space.toml"
    path.write_text(text)
    return load_space(path)


# -- (a) determinism ---------------------------------------------------------------------------


def test_the_same_seed_gives_the_same_files_and_every_file_loads(tmp_path: Path) -> None:
    space = load_space()
    first = generate(space, count=12, seed=7, out_dir=tmp_path / "a")
    again = generate(space, count=12, seed=7, out_dir=tmp_path / "b")
    other = generate(space, count=12, seed=8, out_dir=tmp_path / "c")
    assert [p.name for p in first] == [f"gen-7-{k}.toml" for k in range(12)]
    assert [p.read_bytes() for p in first] == [p.read_bytes() for p in again]
    assert [p.read_bytes() for p in first] != [p.read_bytes() for p in other]
    for path in first:
        spec = load_scenario(path)
        assert spec.invariants is not None
        assert spec.journey is not None
        assert 20.0 <= (spec.journey.max_speed_kmh or 0.0) <= 80.0
        assert spec.journey.timing_points[-1].end_of_journey


def test_a_scenario_does_not_depend_on_how_many_are_drawn(tmp_path: Path) -> None:
    space = load_space()
    few = generate(space, count=2, seed=3, out_dir=tmp_path / "few")
    many = generate(space, count=5, seed=3, out_dir=tmp_path / "many")
    assert few[1].read_bytes() == many[1].read_bytes()


def test_the_legs_are_timed_from_the_plain_lspb(tmp_path: Path) -> None:
    space = _space(tmp_path)
    base = draw(space, 1, 0)
    base = replace(base, cap_kmh=40.0, legs=(replace(base.legs[0], slack=0.0),))
    spec = render(space, base)
    assert spec.journey is not None
    # From ~219 m (the preamble's stop) to north at 550 m under 40 km/h: a short leg.
    expected = plain_lspb_time_s(550.0 - 219.0, 40.0 / 3.6)
    assert spec.journey.timing_points[0].arrival_time_s == pytest.approx(expected, abs=0.2)


def test_outages_that_take_the_localisation_away_make_the_operator_engage_again() -> None:
    """gen-1-122: the IMU out from 97.5 s, the odometer stuck at zero from 108.4 s; the
    localisation was lost, the ATO-OB disengaged and braked to a standstill 900 m short of east,
    and stood ready (RE) for the remote driver's engage until the run ended."""
    space = load_space()
    base = draw(space, 1, 122)
    assert {f.kind for f in base.faults} == {"sensor_dropout", "odometer_failure"}
    assert render(space, base).operator.reengage

    def reengage(*faults: Fault) -> bool:
        return render(space, replace(base, faults=faults)).operator.reengage

    odometer = OdometerFailure(kind="odometer_failure", start_s=100.0, end_s=120.0)
    gps = SensorDropout(kind="sensor_dropout", sensor="gps", start_s=110.0, end_s=150.0)
    imu = SensorDropout(kind="sensor_dropout", sensor="imu", start_s=110.0, end_s=150.0)
    later_imu = imu.model_copy(update={"start_s": 120.0})
    dropout = SensorDropout(kind="sensor_dropout", sensor="odometer", start_s=140.0, end_s=160.0)
    assert reengage(imu, dropout)  # no motion sensor: the filter's health is lost
    assert not reengage(odometer, later_imu)  # one after the other
    assert not reengage(imu, gps)  # the calibrated odometer carries the estimate
    assert not reengage(odometer, gps)  # the IMU with its calibrated bias (gen-1-128: 24 s)
    assert not reengage(odometer)


def test_the_route_comes_back_once_the_train_stands_closed_up_on_the_truth() -> None:
    """gen-1-149: the RBC gave the route back at ETCS's distance under 9 m, 13.7 m short of the
    EoA on the truth (ETCS's odometry 5.4 m ahead); the condition is now the train's true
    position within the invariant's bound of the EoA, as the invariant judges it."""
    default = load_space()
    strict = default.model_copy(
        update={"invariants": default.invariants.model_copy(update={"max_eoa_stop_m": 7.0})}
    )
    for space in (default, strict):
        spec = render(space, draw(space, 1, 149))
        [shortened] = [f for f in spec.faults if isinstance(f, ShortenedAuthority)]
        [route] = [a for a in spec.actions if a.do == "issue_ma"]
        near = shortened.end_of_authority_m - space.invariants.max_eoa_stop_m
        assert route.when == f"standstill and next_stop == tp2-east and position_m >= {near}"


# -- (b) the space file ------------------------------------------------------------------------


def test_the_default_space_loads() -> None:
    space = load_space(DEFAULT_SPACE)
    assert space.line == "bologna-ring"
    assert space.invariants.max_stop_error_m == 0.5


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ("colour = 3\n", "colour: Extra inputs are not permitted"),
        ("", "cap_kmh: Value error, a range"),
        ("[tsr]\nspeed_kmh = [10.0, 999.0]\n", "tsr.speed_kmh must lie within"),
    ],
)
def test_a_bad_space_is_refused_with_where_and_why(
    tmp_path: Path, change: str, message: str
) -> None:
    text = SMALL_SPACE.replace("[tsr]\ncount = [0, 0]\n", "") + change
    if not change:
        text = text.replace("cap_kmh = [30.0, 60.0]", "cap_kmh = [60.0, 30.0]")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(SpaceFileError) as caught:
        load_space(path)
    assert str(path) in str(caught.value)
    assert message.split(": Value error, ")[-1] in str(caught.value)


# -- (c) invariants ----------------------------------------------------------------------------


@pytest.fixture
def small_spec(tmp_path: Path) -> ScenarioSpec:
    return render(_space(tmp_path), draw(_space(tmp_path), 1, 0))


@pytest.mark.parametrize(
    ("changes", "invariant"),
    [
        ({"max_overspeed_kmh": 0.4}, "overspeed_mrsp"),
        ({"max_speed_over_cap_kmh": 1.2}, "overspeed_cap"),
        ({"min_eoa_margin_m": -0.3}, "eoa_passed"),
        (
            {"eoa_stops": [{"time_s": 90.0, "distance_to_eoa_m": 45.2, "odometry_interval_m": 4}]},
            "eoa_stop_far",
        ),
        ({"etcs_sb_count": 1}, "etcs_intervention"),
        ({"etcs_eb_count": 1}, "etcs_intervention"),
        ({"vc_eb_count": 1}, "vc_eb"),
        ({"stops": []}, "stop_missed"),
        (
            {"stops": [sample_kpis().stops[0].model_dump() | {"stop_error_m": -0.7}]},
            "stop_missed",
        ),
        ({"nmpc_failures": 12, "nmpc_fallback_s": 2.4}, "nmpc_unbounded"),
    ],
)
def test_each_invariant_can_fail(
    small_spec: ScenarioSpec, changes: dict[str, Any], invariant: str
) -> None:
    assert judge(small_spec, sample_kpis()) == []
    found = judge(small_spec, sample_kpis(**changes))
    assert [v.invariant for v in found] == [invariant]


def test_a_crash_and_the_excuses(small_spec: ScenarioSpec) -> None:
    crash = judge(small_spec, None, error="Traceback ...\nRuntimeError: boom\n")
    assert crash == [Violation("crash", "RuntimeError: boom")]
    reported = {"stop": "tp1-north", "reason": "timing_infeasible", "at_s": 45.0}
    assert judge(small_spec, sample_kpis(stops=[], journey_reports=[reported])) == []
    detail = "journey not stored (422): leg 0 ... minimum running time 80 s"
    refused = {"action": "send_journey", "at_s": 45.0, "accepted": False, "detail": detail}
    assert judge(small_spec, sample_kpis(stops=[], actions=[refused])) == []
    # An EB a fault asks for: an ATO-OB failure; the stops after it are excused too.
    asked = small_spec.model_copy(update={"faults": (*small_spec.faults, _ato_failure())})
    assert judge(asked, sample_kpis(vc_eb_count=1, stops=[])) == []
    # A few fallback steps are within the bound; a wall-time bound is judged only when set.
    assert judge(small_spec, sample_kpis(nmpc_failures=2, nmpc_fallback_s=0.4)) == []
    slow = sample_kpis(nmpc_ms={"p50": 1.0, "p99": 5.0, "max": 25.0})
    assert judge(small_spec, slow) == []
    timed = InvariantSettings(nmpc_max_ms=20.0)
    found = judge(small_spec, slow, settings=timed)
    assert [v.invariant for v in found] == ["nmpc_unbounded"]
    strict = InvariantSettings(max_stop_error_m=0.05, skip=("nmpc_unbounded",))
    slower = sample_kpis(nmpc_ms={"p50": 1.0, "p99": 5.0, "max": 99.0})
    found = judge(small_spec, slower, settings=strict)
    assert [v.invariant for v in found] == ["stop_missed"]
    assert set(INVARIANTS) >= {"crash", "stop_missed"}


@pytest.mark.parametrize(
    ("kind", "window_s", "reaction_s", "asks"),
    [
        # Absent operator: unseen for the window and one reaction.
        ("vigilance_absent", 5.0, 4.5, False),
        ("vigilance_absent", 6.0, 4.5, True),
        # Lost link (gen-1-84): the answer in flight is lost with it, so a second reaction and
        # the new session's handshake count too: 2.1 + 2 × 4.5 + 2 = 13.1 s ≥ 10 s.
        ("zenoh_link_loss", 2.1, 4.5, True),
        ("zenoh_link_loss", 2.0, 2.9, False),
        ("zenoh_link_loss", 2.0, 3.0, True),
    ],
)
def test_a_lost_operator_or_link_asks_for_the_vc_eb_when_a_vigilance_request_may_be_missed(
    small_spec: ScenarioSpec, kind: str, window_s: float, reaction_s: float, asks: bool
) -> None:
    from deploy.scenario.invariants import faults_asking_for_vc_eb
    from deploy.scenario.schema import VigilanceAbsent, ZenohLinkLoss

    window = {"start_s": 180.0, "end_s": 180.0 + window_s}
    fault = (
        ZenohLinkLoss(kind="zenoh_link_loss", mode="reset", **window)
        if kind == "zenoh_link_loss"
        else VigilanceAbsent(kind="vigilance_absent", **window)
    )
    spec = small_spec.model_copy(
        update={
            "faults": (fault,),
            "operator": small_spec.operator.model_copy(update={"reaction_s": reaction_s}),
        }
    )
    settings = InvariantSettings(vigilance_answer_s=10.0)
    assert bool(faults_asking_for_vc_eb(spec, settings)) is asks
    found = judge(spec, sample_kpis(vc_eb_count=1, stops=[]), settings=settings)
    assert ([v.invariant for v in found] == []) is asks


def _ato_failure() -> Any:
    from deploy.scenario.schema import AtoFailure

    return AtoFailure(kind="ato_failure", start_s=100.0, end_s=110.0)


# -- (d) the shrinker with a fake run ----------------------------------------------------------


def test_the_shrinker_drops_what_does_not_matter_and_keeps_the_cause() -> None:
    space = load_space()
    base = next(
        d for k in range(200) if len((d := draw(space, 5, k)).faults) >= 2 and d.tsrs and d.legs
    )
    culprit = base.faults[-1]

    def fake_run(spec: ScenarioSpec) -> list[Violation]:
        return [Violation("vc_eb", "fake")] if culprit in spec.faults else []

    result = shrink(space, base, "vc_eb", fake_run, max_runs=40)
    assert result.draw.faults == (culprit,)
    assert result.draw.tsrs == ()
    assert result.draw.mas == ()
    assert len(result.draw.legs) == 1
    assert result.draw.cap_kmh == 40.0
    assert result.draw.reaction_s == 1.0
    assert result.spec.name.endswith("-shrunk")
    assert result.runs <= 40 and "drop the last leg" in result.steps or len(base.legs) == 1

    bounded = shrink(space, base, "vc_eb", fake_run, max_runs=2)
    assert bounded.runs == 2


# -- (e) end to end: a real failure, shrunk by real runs, re-run from its file -----------------


@pytest.mark.e2e
def test_a_failing_generated_scenario_is_shrunk_and_ato_run_reproduces_it(
    tmp_path: Path,
) -> None:
    # Stops within a millimetre: a real run serves north a few centimetres off, and fails.
    space = _space(tmp_path, max_stop_error_m=0.001, nmpc_max_ms=10_000.0)
    campaign = run_generated(
        space, count=1, seed=11, out_dir=tmp_path / "gen", workers=1, shrink_runs=2
    )
    [found] = campaign.violations.values()
    assert [v.invariant for v in found] == ["stop_missed"]
    path, result = campaign.shrunk["stop_missed"]
    assert path == tmp_path / "gen" / "gen-11-0-shrunk.toml"
    assert path.is_file()
    assert result.runs == 2
    assert result.steps[0].startswith("drop sensor_dropout")  # irrelevant to the stop
    assert load_scenario(path).faults == ()
    assert run_from_cli(str(path), fast=True, speed=1.0, seed=None, report=None) == 1


@pytest.mark.e2e
def test_five_generated_scenarios_keep_every_invariant(tmp_path: Path) -> None:
    """The small campaign of `make test`: five scenarios of fixed seed, short journeys."""
    out = tmp_path / "gen"
    space = tmp_path / "space.toml"
    space.write_text(SMALL_SPACE.replace("count = [1, 1]", "count = [0, 1]"))
    arguments = [
        "campaign",
        "--generate",
        "5",
        "--seed",
        "2",
        "--space",
        str(space),
        "--out",
        str(out),
        "--workers",
        "2",
        "--shrink-runs",
        "0",
        "--json",
        str(tmp_path / "s.json"),
    ]
    result = CliRunner().invoke(app, arguments)
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["runs"] == 5
    assert len(list(out.glob("gen-2-*.toml"))) == 5
    assert summary["invariants"] == {}, result.output
    assert result.exit_code == 0
    kept = {path.name: path.read_text() for path in (out / "results").glob("gen-2-*.json")}
    assert len(kept) == 5
    # Resumed: the kept results taken back, not run again (a new run would be written out with
    # its own wall-clock times); the one without a result run.
    (out / "results" / "gen-2-3.json").unlink()
    resumed = CliRunner().invoke(app, [*arguments, "--resume"])
    assert resumed.exit_code == 0, resumed.output
    assert json.loads((tmp_path / "s.json").read_text())["runs"] == 5
    again = {path.name: path.read_text() for path in (out / "results").glob("gen-2-*.json")}
    assert [name for name in kept if again[name] != kept[name]] == ["gen-2-3.json"]
