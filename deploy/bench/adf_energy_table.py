"""The energy planner leg by leg (issue 22): ours against the offline optimum and the plain LSPB.

For each leg: the traction energy at the wheel of our plan (``onboard.adf.odp_journey``), of the
plain LSPB (``onboard.adf.odp.plan_legs``) and of the offline optimum
(``onboard.adf.energy.optimal_leg``, IPOPT collocation) for the same leg, time and limits; the
time slack (the scheduled time over the fastest our builder can drive under the same limits,
less one); whether the leg kept the LSPB (a fallback); the plan's processor time (the planner
is single-threaded Python; its wall time on a loaded machine is the processor time and the
waits).

The optimum brakes as the plan does: at most ``MAX_BRAKING_MPS2`` in total (brake, resistance
and gradient together; its brake force also limited to that rate × M(1 + ρ)). The plan brakes
into its stops at 0.7 m/s² on purpose (the NMPC's margin to the URV's 0.93 m/s² brake), and an
optimum braking harder gains its time there, not in the driving (docs/energy-planning.md). A
leg with a passing point is compared with the optimum that passes it at the same time (an
interior time constraint of ``optimal_leg``).

Legs: the three of the bologna-ring field-test lap, three of milano-bologna (speed-limit
changes at up to 200 km/h, a 30 km leg at 200 km/h with a 10 ‰ hill, a 14 km leg over a 12 ‰
hill and descent), a ring leg with a passing point, and the legs of the scenario generator's
draws (default space, seed 1) until ``generated`` legs are collected.
"""

from __future__ import annotations

import dataclasses
import statistics
import time
from dataclasses import dataclass

from rich.console import Console
from rich.table import Table

from deploy.scenario.generate import draw, render
from deploy.scenario.line_source import stored_line
from deploy.scenario.space import GeneratorSpace, load_space
from onboard.adf.energy import optimal_leg, plan_traction_energy_j
from onboard.adf.odp import InfeasibleLegError, plan_legs
from onboard.adf.odp_energy import MAX_BRAKING_MPS2, LegTrack, build_profile
from onboard.adf.odp_journey import PassingPoint, plan_energy_journey
from onboard.plant import URV_PARAMETERS
from onboard.plant.point_mass import PointMassParameters
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap, load_seed_line

__all__ = [
    "BenchLeg",
    "LegResult",
    "energy_table",
    "generated_legs",
    "leg_result",
    "named_legs",
    "summary",
]

GENERATED_SEED = 1
TARGET_ABOVE_OPTIMUM, BAR_ABOVE_OPTIMUM = 1.0, 2.0
"""Ours over the optimum [%]."""
TARGET_BELOW_LSPB, SLACK_FOR_LSPB = 10.0, 0.05
"""Ours under the plain LSPB [%] on legs with at least this time slack."""


@dataclass(frozen=True)
class BenchLeg:
    name: str
    track_map: TrackMap
    start_chainage_m: float
    distance_m: float
    duration_s: float
    cap_mps: float | None
    passing: tuple[tuple[float, float], ...] = ()
    """(offset into the leg [m], time from its departure [s])."""


@dataclass(frozen=True)
class LegResult:
    name: str
    distance_m: float
    ours_j: float
    lspb_j: float
    optimum_j: float | None
    """None when IPOPT did not converge."""
    slack: float
    fallback: bool
    plan_s: float
    """Processor time of the plan [s]."""

    @property
    def above_optimum_pct(self) -> float | None:
        return None if self.optimum_j is None else 100.0 * (self.ours_j / self.optimum_j - 1.0)

    @property
    def below_lspb_pct(self) -> float:
        return 100.0 * (1.0 - self.ours_j / self.lspb_j)


def named_legs() -> list[BenchLeg]:
    """The ring's lap, three milano-bologna legs and a ring leg with a passing point."""
    ring = TrackMap(load_seed_line("bologna-ring"))
    line = TrackMap(load_seed_line("milano-bologna"))
    ring_cap, line_cap = 40 * MPS_PER_KMH, 200 * MPS_PER_KMH
    return [
        BenchLeg("ring lap: start → east", ring, 200.0, 1775.0, 300.0, ring_cap),
        BenchLeg("ring lap: east → south", ring, 1975.0, 1425.0, 230.0, ring_cap),
        BenchLeg("ring lap: south → north", ring, 3400.0, 2850.0, 430.0, ring_cap),
        BenchLeg("m-b: Rogoredo → Lodi, 3 limits", line, 500.0, 29500.0, 1000.0, line_cap),
        BenchLeg("m-b: Reggio → Modena, 200 km/h", line, 128000.0, 30000.0, 700.0, line_cap),
        BenchLeg("m-b: 12 ‰ hill and descent", line, 44000.0, 14000.0, 400.0, line_cap),
        BenchLeg(
            "ring: south → north, passing 1.4 km at 190 s",
            ring,
            3400.0,
            2850.0,
            430.0,
            ring_cap,
            passing=((1400.0, 190.0),),
        ),
    ]


def generated_legs(count: int, space: GeneratorSpace | None = None) -> list[BenchLeg]:
    """The first ``count`` legs of the generator's draws of :data:`GENERATED_SEED` whose plain
    LSPB is feasible (the others' journeys are refused on board)."""
    space = space or load_space()
    track_map = TrackMap(stored_line(space.line))
    stops = {p.id: p.position_m for p in track_map.line.stopping_points}
    legs: list[BenchLeg] = []
    index = 0
    while len(legs) < count:
        item = draw(space, GENERATED_SEED, index)
        spec = render(space, item)
        assert spec.journey is not None  # a generated scenario always has one
        here = _journey_start_m(track_map, item.start_position_m)
        departure = 0.0
        cap = spec.journey.max_speed_kmh * MPS_PER_KMH if spec.journey.max_speed_kmh else None
        for k, point in enumerate(spec.journey.timing_points):
            to_m = stops[point.stopping_point_id or ""]
            length = (to_m - here) % track_map.length_m if track_map.line.ring else to_m - here
            name = f"gen-{GENERATED_SEED}-{index} leg {k + 1}"
            duration = point.arrival_time_s - departure
            leg = BenchLeg(name, track_map, here, length, duration, cap)
            if _lspb_feasible(leg):  # else the journey is refused: no plan to judge
                legs.append(leg)
            here, departure = to_m, point.departure_time_s or point.arrival_time_s
        index += 1
    return legs[:count]


def _lspb_feasible(leg: BenchLeg) -> bool:
    stops = [(leg.distance_m, leg.duration_s, leg.duration_s)]
    try:
        plan_legs(
            leg.track_map, start_chainage_m=leg.start_chainage_m, stops=stops, cap_mps=leg.cap_mps
        )
    except InfeasibleLegError:
        return False
    return True


def _journey_start_m(track_map: TrackMap, start_m: float) -> float:
    from deploy.scenario.generate import _journey_start_m as start  # the generator's own rule

    return start(track_map, start_m)


def _brake_limited(model: PointMassParameters) -> PointMassParameters:
    effective = model.mass_kg * (1.0 + model.rotating_mass_factor)
    return dataclasses.replace(model, max_brake_force_n=MAX_BRAKING_MPS2 * effective)


def _fastest_s(leg: BenchLeg, model: PointMassParameters) -> float:
    track = LegTrack(
        leg.track_map,
        model,
        start_chainage_m=leg.start_chainage_m,
        distance_m=leg.distance_m,
        cap_mps=leg.cap_mps,
    )
    top = float(track.ceilings_mps.max())
    return build_profile(track, holding_speed_mps=top).duration_s


def _optimum_step_m(distance_m: float) -> float:
    """The collocation's step [m]: 150 intervals on a short leg (10 m steps gave ±2 % of
    discretisation error on a 330 m one), at most 10 m up to 6 km, 600 intervals beyond."""
    return max(distance_m / 600.0, min(10.0, max(1.0, distance_m / 150.0)))


def leg_result(leg: BenchLeg, model: PointMassParameters = URV_PARAMETERS) -> LegResult:
    """One leg measured: ours, the LSPB, the optimum, the slack, the fallback, the plan time.

    Raises
    ------
    InfeasibleLegError
        When the leg's plain LSPB is infeasible (the journey would be refused).
    """
    stops = [(leg.distance_m, leg.duration_s, leg.duration_s)]
    start = leg.start_chainage_m
    lspb = plan_legs(leg.track_map, start_chainage_m=start, stops=stops, cap_mps=leg.cap_mps)
    passing = [PassingPoint(f"p{k}", d, t) for k, (d, t) in enumerate(leg.passing)]
    started = time.process_time()
    ours = plan_energy_journey(
        leg.track_map,
        model,
        start_chainage_m=start,
        stops=stops,
        passing=passing,
        cap_mps=leg.cap_mps,
    )
    plan_s = time.process_time() - started
    try:
        optimum: float | None = optimal_leg(
            leg.track_map,
            _brake_limited(model),
            start_chainage_m=start,
            distance_m=leg.distance_m,
            duration_s=leg.duration_s,
            cap_mps=leg.cap_mps,
            step_m=_optimum_step_m(leg.distance_m),
            max_deceleration_mps2=MAX_BRAKING_MPS2,
            passing=leg.passing,
        ).traction_energy_j
    except RuntimeError:  # IPOPT did not converge
        optimum = None
    return LegResult(
        name=leg.name,
        distance_m=leg.distance_m,
        ours_j=plan_traction_energy_j(ours.plan, model),
        lspb_j=plan_traction_energy_j(lspb, model),
        optimum_j=optimum,
        slack=leg.duration_s / _fastest_s(leg, model) - 1.0,
        fallback=ours.kept_plain > 0,
        plan_s=plan_s,
    )


def summary(results: list[LegResult]) -> dict[str, float]:
    """Max % above the optimum, min % below the LSPB where the slack is ≥ 5 %, fallbacks,
    optimum failures, plan time median and max [s]."""
    above = [r.above_optimum_pct for r in results if r.above_optimum_pct is not None]
    below = [r.below_lspb_pct for r in results if r.slack >= SLACK_FOR_LSPB]
    times = [r.plan_s for r in results]
    return {
        "legs": float(len(results)),
        "max_above_optimum_pct": max(above) if above else float("nan"),
        "min_below_lspb_pct": min(below) if below else float("nan"),
        "fallbacks": float(sum(r.fallback for r in results)),
        "optimum_failures": float(sum(r.optimum_j is None for r in results)),
        "plan_median_s": statistics.median(times),
        "plan_max_s": max(times),
    }


def energy_table(console: Console, *, generated: int = 100) -> dict[str, float]:
    """Measure the named legs and ``generated`` generated ones; print the table and summary."""
    legs = named_legs() + generated_legs(generated) if generated else named_legs()
    results: list[LegResult] = []
    for leg in legs:
        try:
            results.append(leg_result(leg))
        except InfeasibleLegError as exc:
            console.print(f"{leg.name}: the plain LSPB is infeasible ({exc}); left out")
    table = Table(title="Energy plans leg by leg: ours against the optimum (b) and the LSPB (a)")
    for column in ("leg", "km", "vs (b)", "vs (a)", "slack", "fallback", "plan CPU s"):
        table.add_column(column, justify="left" if column == "leg" else "right")
    for r in results:
        above = r.above_optimum_pct
        table.add_row(
            r.name,
            f"{r.distance_m / 1000:.2f}",
            "—" if above is None else f"{above:+.2f} %",
            f"{-r.below_lspb_pct:+.1f} %",
            f"{100 * r.slack:.1f} %",
            "yes" if r.fallback else "no",
            f"{r.plan_s:.2f}",
        )
    console.print(table)
    figures = summary(results)
    console.print(
        f"{figures['legs']:.0f} legs: max {figures['max_above_optimum_pct']:+.2f} % above the "
        f"optimum (target ≤ {TARGET_ABOVE_OPTIMUM:g} %, bar ≤ {BAR_ABOVE_OPTIMUM:g} %); min "
        f"{figures['min_below_lspb_pct']:.1f} % below the LSPB where the slack is ≥ "
        f"{100 * SLACK_FOR_LSPB:g} % (target ≥ {TARGET_BELOW_LSPB:g} %); fallbacks "
        f"{figures['fallbacks']:.0f} (target 0); IPOPT did not converge on "
        f"{figures['optimum_failures']:.0f}; plan processor time median "
        f"{figures['plan_median_s']:.2f} s, max {figures['plan_max_s']:.2f} s"
    )
    return figures
