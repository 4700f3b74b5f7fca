"""The scenario generator: whole-stack scenarios drawn from a space, written as scenario files.

Scenario ``index`` of seed ``S`` is drawn from ``numpy.random.default_rng([S, index])`` alone, so
a scenario does not change when the campaign around it grows, and the same seed gives the same
files byte for byte. A draw (:class:`Draw`) holds the drawn values; :func:`render` turns it into
an ordinary :class:`ScenarioSpec` with the library's preamble (``bologna-ring``: remote driving
in SR at 30 km/h to the balise group that brings FS, a stop, the journey sent, AD engaged). The
shrinker (``deploy.scenario.shrink``) edits draws and renders them again.

Timing: each leg's scheduled running time is its *plain LSPB time* times ``1 + slack``. The plain
LSPB time is the time of the ADF's plain LSPB (``onboard.adf.odp``) at its comfort acceleration
(0.5 m/s² both ways) cruising at the leg's speed limit (the lowest MRSP along the leg, and the
journey's cap): Δ/v + v/a, or 2·√(Δ/a) on a leg too short to reach v. Times are from the
journey's start (its acceptance on board, ~45 s into the run on the ring); the first leg
departs at 0.

TSRs and MA shortenings come into force at a place relative to the train, by a condition
(``next_stop == tp2-south and position_m >= 2601.5``), not at a time: exact and reproducible.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from deploy.scenario.line_source import stored_line
from deploy.scenario.schema import (
    SHORTENED_DANGER_POINT_M,
    Action,
    AtoFailure,
    Fault,
    JourneySpec,
    OdometerFailure,
    OperatorSpec,
    ScenarioSpec,
    SensorDropout,
    ShortenedAuthority,
    TemporarySpeedRestriction,
    UdpLinkFault,
    VigilanceAbsent,
    ZenohLinkLoss,
)
from deploy.scenario.space import GeneratorSpace
from deploy.scenario.toml_out import scenario_toml
from onboard.adf.odp import COMFORT_ACCELERATION_MPS2, leg_speed_limit_mps
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap
from trackdb.journey import JourneyTimingPoint

__all__ = [
    "Draw",
    "LegDraw",
    "MaDraw",
    "TsrDraw",
    "default_out_dir",
    "draw",
    "generate",
    "plain_lspb_time_s",
    "render",
    "write_scenario",
]

JOURNEY_START_AFTER_BALISE_M = 70.0
"""The preamble's stop lies about this far past the balise group that brings FS [m] (30 km/h
in RD, then the stop; 219 m for the group at 150 m on the ring)."""
PREAMBLE_S = 60.0
"""Simulated time the preamble takes, with room (the journey is accepted at ~45 s) [s]."""
LIMIT_DECELERATION_MPS2 = 0.5
REACTION_S = 6.0
INTERVAL_MARGIN_M = 90.0
"""The braking point of a lower limit as the ADF's planner keeps it (docs/decisions.md,
"Braking into a lower limit"): v·6 s + (v² − w²)/(2·0.5 m/s²), 10 m and the odometry interval
(5 % of up to 1.65 km between balise groups, rounded up) before it."""
LEG_MARGIN_M = 40.0
"""Nothing is put within this distance of a leg's ends [m]."""
RESTORE_BEHIND_M = 200.0
"""A restored MA ends this far behind the shortened stop, nearly a lap ahead on a ring [m]."""
FALLBACK_FAULTS = ("zenoh_link_loss", "ato_failure", "vigilance_absent")
"""Faults that can end in a fallback stop, after which the operator engages ATO again."""
MOTION_SENSORS = frozenset({"imu", "odometer"})
"""Sensors whose outages together take the fused localisation away: with neither the IMU nor
the odometer the filter's health is lost, the ATO-OB disengages, brakes to a standstill and
waits for the remote driver's engage (docs/truth_boundary.md, "Localisation valid"), so the
operator engages ATO again. The GPS out with the odometer leaves the IMU with its calibrated
bias: gen-1-128 rode through 24 s of it."""


@dataclass(frozen=True)
class LegDraw:
    stop_id: str
    slack: float
    dwell_s: float


@dataclass(frozen=True)
class TsrDraw:
    leg: int
    placement: str
    where: float
    """Where in the leg the TSR starts, as a share of the room there is [0, 1]."""
    length_m: float
    speed_kmh: float
    lead_m: float
    """``inside_leg``: distance past the braking point; ``braking_point``: the margin [m]."""


@dataclass(frozen=True)
class MaDraw:
    leg: int
    placement: str
    """``before`` or ``beyond`` the leg's stop."""
    offset_m: float
    where: float
    """Where in the leg the shortening comes, as a share of the room there is [0, 1]."""


@dataclass(frozen=True)
class Draw:
    """The drawn values of one generated scenario."""

    seed: int
    index: int
    run_seed: int
    """The run's own seed (sensor noise, link draws)."""
    start_position_m: float
    cap_kmh: float
    reaction_s: float
    legs: tuple[LegDraw, ...]
    tsrs: tuple[TsrDraw, ...] = ()
    mas: tuple[MaDraw, ...] = ()
    faults: tuple[Fault, ...] = ()
    suffix: str = ""
    """Appended to the name (``-shrunk``)."""

    @property
    def name(self) -> str:
        return f"gen-{self.seed}-{self.index}{self.suffix}"


def plain_lspb_time_s(distance_m: float, limit_mps: float) -> float:
    """The plain LSPB's running time over ``distance_m`` [m] under ``limit_mps`` [m/s] [s]."""
    a = COMFORT_ACCELERATION_MPS2
    if limit_mps * limit_mps / a >= distance_m:
        return 2.0 * math.sqrt(distance_m / a)
    return distance_m / limit_mps + limit_mps / a


def _uniform(rng: np.random.Generator, bounds: tuple[float, float], digits: int) -> float:
    return round(float(rng.uniform(bounds[0], bounds[1])), digits)


def _integer(rng: np.random.Generator, bounds: tuple[int, int]) -> int:
    return int(rng.integers(bounds[0], bounds[1] + 1))


def _choice(rng: np.random.Generator, weights: Mapping[Any, float]) -> str:
    names = sorted(name for name, weight in weights.items() if weight > 0.0)
    shares = np.asarray([weights[name] for name in names])
    return str(names[int(rng.choice(len(names), p=shares / shares.sum()))])


def _journey_start_m(track_map: TrackMap, start_m: float) -> float:
    """Where the preamble stops: past the first balise group with an MA ahead of ``start_m``."""
    groups = [
        g.position_m
        for g in track_map.line.balise_groups
        if any(p.type == "movement_authority" for p in g.packets)
    ]
    if not groups:
        return start_m
    ahead = min(groups, key=lambda g: _forward(track_map, start_m, g))
    return track_map.normalise(ahead + JOURNEY_START_AFTER_BALISE_M)


def _forward(track_map: TrackMap, from_m: float, to_m: float) -> float:
    if track_map.line.ring:
        return (to_m - from_m) % track_map.length_m
    return to_m - from_m


def _stops(
    rng: np.random.Generator, space: GeneratorSpace, track_map: TrackMap, start_m: float, count: int
) -> list[str]:
    """The platforms the legs run to: each the next ahead, or with ``skip_platform`` the one
    after; the first at least a leg's margins ahead of the start."""
    points = sorted(track_map.line.stopping_points, key=lambda p: p.position_m)
    chosen: list[str] = []
    here = start_m
    for _ in range(count):
        ahead = sorted(points, key=lambda p: _forward(track_map, here, p.position_m) or math.inf)
        ahead = [p for p in ahead if _forward(track_map, here, p.position_m) > 2 * LEG_MARGIN_M]
        if not ahead:
            break
        step = 1 if len(ahead) > 1 and rng.random() < space.skip_platform else 0
        point = ahead[step]
        chosen.append(point.id)
        here = point.position_m
    return chosen


def draw(space: GeneratorSpace, seed: int, index: int) -> Draw:
    """Scenario ``index`` of ``seed``."""
    rng = np.random.default_rng([seed, index])
    run_seed = int(rng.integers(2**31))
    track_map = TrackMap(stored_line(space.line))
    start = float(space.start_position_m[int(rng.integers(len(space.start_position_m)))])
    cap = _uniform(rng, space.cap_kmh, 0)
    reaction = _uniform(rng, space.reaction_s, 1)
    stops = _stops(
        rng, space, track_map, _journey_start_m(track_map, start), _integer(rng, space.legs)
    )
    legs = tuple(
        LegDraw(stop, _uniform(rng, space.slack, 3), _uniform(rng, space.dwell_s, 0))
        for stop in stops
    )
    tsrs = tuple(
        TsrDraw(
            leg=int(rng.integers(len(legs))),
            placement=_choice(rng, space.tsr.placement),
            where=_uniform(rng, (0.0, 1.0), 3),
            length_m=_uniform(rng, space.tsr.length_m, 0),
            speed_kmh=5.0 * round(_uniform(rng, space.tsr.speed_kmh, 1) / 5.0),
            lead_m=_uniform(rng, space.tsr.braking_point_margin_m, 0),
        )
        for _ in range(_integer(rng, space.tsr.count))
    )
    ma_legs = rng.permutation(len(legs))[: _integer(rng, space.ma.count)]
    mas = []
    for leg in sorted(int(k) for k in ma_legs):
        placement = _choice(rng, space.ma.placement)
        bounds = space.ma.before_m if placement == "before" else space.ma.beyond_m
        mas.append(MaDraw(leg, placement, _uniform(rng, bounds, 0), _uniform(rng, (0.0, 1.0), 3)))
    base = Draw(seed, index, run_seed, start, cap, reaction, legs, tsrs, tuple(mas))
    return replace(base, faults=_draw_faults(rng, space, base))


def _draw_faults(rng: np.random.Generator, space: GeneratorSpace, base: Draw) -> tuple[Fault, ...]:
    """Sensor, link and operator faults, each in a window drawn over the journey."""
    end_s = PREAMBLE_S + _timing(space, base)[-1][0]
    kinds = {name: kind.weight for name, kind in space.faults.kinds.items()}
    faults: list[Fault] = []
    for _ in range(_integer(rng, space.faults.count)):
        name = _choice(rng, kinds)
        kind = space.faults.kinds[name]  # type: ignore[index]
        start = _uniform(rng, (PREAMBLE_S - 10.0, end_s), 1)
        window = {"start_s": start, "end_s": round(start + _uniform(rng, kind.window_s, 1), 1)}
        if name == "sensor_dropout":
            sensor = ("imu", "odometer", "gps")[int(rng.integers(3))]
            faults.append(SensorDropout(kind=name, sensor=sensor, **window))
        elif name == "odometer_failure":
            mode = ("silent", "stuck_zero")[int(rng.integers(2))]
            faults.append(OdometerFailure(kind=name, mode=mode, **window))
        elif name == "udp_link":
            rates = {
                key: _uniform(rng, kind.rate, 2)
                for key in ("loss", "reorder", "duplicate", "corrupt")
            }
            if not any(isinstance(f, UdpLinkFault) for f in faults):  # one per scenario
                faults.append(UdpLinkFault(kind=name, **rates, **window))
        elif name == "zenoh_link_loss":
            mode = ("silent", "reset")[int(rng.integers(2))]
            faults.append(ZenohLinkLoss(kind=name, mode=mode, **window))
        elif name == "vigilance_absent":
            faults.append(VigilanceAbsent(kind=name, **window))
        else:
            faults.append(AtoFailure(kind="ato_failure", **window))
    return tuple(faults)


@dataclass(frozen=True)
class _Leg:
    """A leg's geometry: from chainage ``start_m`` over ``length_m`` to its stop."""

    start_m: float
    length_m: float
    stop_m: float
    limit_mps: float
    """The leg's cruise limit: the lowest MRSP along it, and the cap [m/s]."""
    top_mps: float
    """The highest speed the train may reach in it: the highest MRSP, and the cap [m/s]."""


def _geometry(space: GeneratorSpace, base: Draw) -> tuple[TrackMap, list[_Leg]]:
    track_map = TrackMap(stored_line(space.line))
    stops = {p.id: p.position_m for p in track_map.line.stopping_points}
    cap = base.cap_kmh * MPS_PER_KMH
    here = _journey_start_m(track_map, base.start_position_m)
    legs = []
    for leg in base.legs:
        length = _forward(track_map, here, stops[leg.stop_id])
        samples = [track_map.mrsp_mps(here + length * k / 50) for k in range(51)]
        limit = min(leg_speed_limit_mps(track_map, here, length), cap)
        legs.append(_Leg(here, length, stops[leg.stop_id], limit, min(max(samples), cap)))
        here = stops[leg.stop_id]
    return track_map, legs


def _timing(space: GeneratorSpace, base: Draw) -> list[tuple[float, float]]:
    """(arrival, departure) of each leg's stop [s from the journey's start]."""
    _, geometry = _geometry(space, base)
    times = []
    departure = 0.0
    for leg, shape in zip(base.legs, geometry, strict=True):
        running = plain_lspb_time_s(shape.length_m, shape.limit_mps) * (1.0 + leg.slack)
        arrival = round(departure + running, 1)
        departure = round(arrival + leg.dwell_s, 1)
        times.append((arrival, departure))
    return times


def _braking_m(speed_mps: float, to_mps: float) -> float:
    return (
        speed_mps * REACTION_S
        + max(speed_mps**2 - to_mps**2, 0.0) / (2.0 * LIMIT_DECELERATION_MPS2)
        + INTERVAL_MARGIN_M
    )


def _in_leg(track_map: TrackMap, leg: _Leg, stop_tp: str, along_m: float) -> str:
    """The condition that holds once the train, running to ``stop_tp``, is ``along_m`` into
    the leg (exact on a ring: a chainage past the line's end wraps, the stop bounds it)."""
    chainage = round(track_map.normalise(leg.start_m + along_m), 1)
    clause = f"next_stop == {stop_tp} and position_m >= {chainage}"
    if chainage < leg.start_m:  # past the ring's end: not before the wrap
        clause += f" and position_m < {round(leg.stop_m, 1)}"
    return clause


def _tsr_fault(
    track_map: TrackMap, legs: list[_Leg], tsr: TsrDraw, tp: str
) -> TemporarySpeedRestriction | None:
    leg = legs[tsr.leg]
    speed = tsr.speed_kmh * MPS_PER_KMH
    room = leg.length_m - 2 * LEG_MARGIN_M
    lead = _braking_m(leg.top_mps, speed) + (tsr.lead_m if tsr.placement != "ahead" else 0.0)
    when = f"next_stop == {tp}"
    along = LEG_MARGIN_M + tsr.where * room
    if tsr.placement != "ahead" and room - lead > 0.0:
        along = LEG_MARGIN_M + lead + tsr.where * (room - lead)
        when = _in_leg(track_map, leg, tp, along - lead)
    start = round(track_map.normalise(leg.start_m + along), 1)
    end = min(start + tsr.length_m, track_map.length_m)
    if end - start < 20.0:
        return None
    return TemporarySpeedRestriction(
        kind="tsr", when=when, start_m=start, end_m=round(end, 1), speed_kmh=tsr.speed_kmh
    )


def _ma_events(
    track_map: TrackMap, legs: list[_Leg], ma: MaDraw, tps: list[str], *, closed_up_m: float
) -> tuple[ShortenedAuthority, Action | None] | None:
    """The shortening, and the RBC's new MA once the train stands at it (none after the last
    stop), within ``closed_up_m`` of an EoA short of the stop; None when the leg has no room."""
    leg = legs[ma.leg]
    eoa_along = leg.length_m + (ma.offset_m if ma.placement == "beyond" else -ma.offset_m)
    latest = eoa_along - _braking_m(leg.top_mps, 0.0)
    # After any group with an MA before the EoA: its packet 12 would replace the shortening.
    earliest = max(
        [LEG_MARGIN_M]
        + [
            a + 10.0
            for g in track_map.line.balise_groups
            if 0.0 <= (a := _forward(track_map, leg.start_m, g.position_m)) < eoa_along
            and any(p.type == "movement_authority" for p in g.packets)
        ]
    )
    if latest <= earliest or eoa_along <= LEG_MARGIN_M:
        return None
    trigger = earliest + ma.where * (latest - earliest)
    eoa = round(track_map.normalise(leg.start_m + eoa_along), 1)
    # The SvL is supervised from the max-safe front end: the danger point covers the interval
    # there (5 m + 5 % from the last group, and the location accuracies).
    behind = [
        d
        for g in track_map.line.balise_groups
        if (d := _forward(track_map, g.position_m, eoa)) >= 0.0
    ]
    danger = max(SHORTENED_DANGER_POINT_M, float(math.ceil(10.0 + 0.05 * min(behind, default=eoa))))
    fault = ShortenedAuthority(
        kind="ma_shortened",
        when=_in_leg(track_map, leg, tps[ma.leg], trigger),
        end_of_authority_m=eoa,
        danger_point_m=danger,
    )
    if ma.placement == "beyond" and ma.leg == len(legs) - 1:
        return fault, None
    near = round(0.1 * (eoa_along - trigger) + 60.0 + max(ma.offset_m, 0.0), 1)
    when = f"standstill and eoa_distance_m < {near}"
    if ma.placement == "before":
        # Once the train stands closed up to the EoA, on the truth as the invariant judges it
        # (docs/decisions.md, "Closing up to an EoA"): ETCS's distance is off by its odometry's
        # drift, metres 1.5 km past a balise group.
        when = "standstill and " + _in_leg(track_map, leg, tps[ma.leg], eoa_along - closed_up_m)
    behind_m = min(eoa_along, leg.length_m) - RESTORE_BEHIND_M  # behind the EoA short of the stop
    restore = (
        track_map.normalise(leg.start_m + behind_m)
        if track_map.line.ring
        else (track_map.length_m - 1.0)
    )
    return fault, Action(do="issue_ma", when=when, end_of_authority_m=round(restore, 1))


def _preamble() -> list[Action]:
    return [
        Action(do="rd_target_speed", when="not vc_eb", speed_kmh=30.0),
        Action(do="rd_target_speed", when="etcs_mode == FS", speed_kmh=0.0),
        Action(do="send_journey", when="standstill"),
        Action(do="engage", when="ato_state == RE"),
    ]


def render(space: GeneratorSpace, base: Draw) -> ScenarioSpec:
    """The scenario of a draw."""
    track_map, legs = _geometry(space, base)
    times = _timing(space, base)
    tps = [f"tp{k + 1}-{leg.stop_id}" for k, leg in enumerate(base.legs)]
    points = []
    for k, (leg, (arrival, departure)) in enumerate(zip(base.legs, times, strict=True)):
        last = k == len(base.legs) - 1
        points.append(
            JourneyTimingPoint(
                id=tps[k],
                stopping_point_id=leg.stop_id,
                arrival_time_s=arrival,
                departure_time_s=None if last else departure,
                end_of_journey=last,
            )
        )
    faults: list[Fault] = []
    for tsr in base.tsrs:
        fault = _tsr_fault(track_map, legs, tsr, tps[tsr.leg])
        if fault is not None:
            faults.append(fault)
    actions = _preamble()
    for ma in base.mas:
        events = _ma_events(track_map, legs, ma, tps, closed_up_m=space.invariants.max_eoa_stop_m)
        if events is not None:
            faults.append(events[0])
            if events[1] is not None:
                actions.append(events[1])
    faults.extend(base.faults)
    return ScenarioSpec(
        name=base.name,
        title=_title(base),
        line=space.line,
        seed=base.run_seed,
        duration_s=round(PREAMBLE_S + times[-1][0] + space.duration_margin_s, 0),
        end_when="journey_ended and standstill",
        vehicle=space.vehicle.model_copy(update={"start_position_m": base.start_position_m}),
        operator=OperatorSpec(
            simulated=True,
            reaction_s=base.reaction_s,
            reengage=any(f.kind in FALLBACK_FAULTS for f in base.faults)
            or _localisation_can_be_lost(base.faults),
        ),
        journey=JourneySpec(
            id="generated", max_speed_kmh=base.cap_kmh, timing_points=tuple(points)
        ),
        actions=tuple(actions),
        faults=tuple(faults),
        invariants=space.invariants,
    )


def _localisation_can_be_lost(faults: tuple[Fault, ...]) -> bool:
    """Whether outages of both :data:`MOTION_SENSORS` overlap in time."""
    outages = [
        ("odometer" if isinstance(f, OdometerFailure) else f.sensor, f.start_s, f.end_s)
        for f in faults
        if isinstance(f, SensorDropout | OdometerFailure)
    ]
    return any(
        {a[0], b[0]} == MOTION_SENSORS and a[1] < b[2] and b[1] < a[2]
        for a in outages
        for b in outages
    )


def _title(base: Draw) -> str:
    parts = [f"{len(base.legs)} legs at ≤ {base.cap_kmh:g} km/h"]
    if base.tsrs:
        parts.append(f"{len(base.tsrs)} TSR")
    if base.mas:
        parts.append(f"{len(base.mas)} MA shortening")
    if base.faults:
        parts.append(", ".join(f.kind for f in base.faults))
    return "Generated: " + "; ".join(parts)


def _comment(space: GeneratorSpace, base: Draw) -> str:
    legs = ", ".join(
        f"{leg.stop_id} (slack {leg.slack:+.3f}, dwell {leg.dwell_s:g} s)" for leg in base.legs
    )
    lines = [
        f"Generated by `ato campaign --generate` from the space {space.name!r}: seed "
        f"{base.seed}, index {base.index}.",
        f"Start {base.start_position_m:g} m, cap {base.cap_kmh:g} km/h, operator reaction "
        f"{base.reaction_s:g} s; legs: {legs}.",
    ]
    track_map, geometry = _geometry(space, base)
    tps = [f"tp{k + 1}-{leg.stop_id}" for k, leg in enumerate(base.legs)]
    left_out = " (left out: no room for it in the leg)"
    closed_up = space.invariants.max_eoa_stop_m
    lines += [
        f"TSR in leg {t.leg + 1}: {t.placement}, {t.speed_kmh:g} km/h over {t.length_m:g} m"
        + ("" if _tsr_fault(track_map, geometry, t, tps[t.leg]) else left_out)
        for t in base.tsrs
    ]
    lines += [
        f"MA shortened in leg {a.leg + 1}: {a.offset_m:g} m {a.placement} the stop"
        + ("" if _ma_events(track_map, geometry, a, tps, closed_up_m=closed_up) else left_out)
        for a in base.mas
    ]
    lines.append("Re-run: ato run THIS_FILE --fast (the invariants are its expectations).")
    return "\n".join(lines)


def write_scenario(space: GeneratorSpace, base: Draw, out_dir: Path) -> Path:
    """The scenario file of a draw, ``<name>.toml`` in ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{base.name}.toml"
    path.write_text(
        scenario_toml(render(space, base), comment=_comment(space, base)), encoding="utf-8"
    )
    return path


def default_out_dir(seed: int) -> Path:
    return Path(".ato") / "generated" / f"seed-{seed}"


def generate(space: GeneratorSpace, *, count: int, seed: int, out_dir: Path) -> list[Path]:
    """Draw ``count`` scenarios of ``seed`` and write them: their paths, in index order."""
    return [write_scenario(space, draw(space, seed, index), out_dir) for index in range(count)]
