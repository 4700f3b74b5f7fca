"""Shrinking a failing generated scenario to the simplest one that still fails the same way.

Greedy, on the draw (``deploy.scenario.generate.Draw``), so that every candidate is rendered
again into a consistent scenario (a lower cap re-times the legs; a dropped leg takes its TSRs
and MA shortenings with it). The candidates, simplest first: drop each fault, each TSR, each
MA shortening; drop the last leg; then move the values to the library's (the space's
``[shrink_to]``: cap 40 km/h, slack +0.4, dwell 20 s, reaction 1 s), all at once, and failing
that half way. A candidate is kept when its run (same run seed) still violates the invariant;
the search starts again from it. At most ``max_runs`` runs.

The run is a function passed in (:data:`RunJudge`), so that the search is tested with a fake.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from typing import TypeVar

from deploy.scenario.generate import Draw, LegDraw, render
from deploy.scenario.invariants import Violation
from deploy.scenario.schema import InvariantName, ScenarioSpec
from deploy.scenario.space import GeneratorSpace

__all__ = ["RunJudge", "ShrinkResult", "candidates", "shrink"]

RunJudge = Callable[[ScenarioSpec], Sequence[Violation]]
"""Run a scenario and judge it: its violations."""


@dataclass(frozen=True)
class ShrinkResult:
    draw: Draw
    spec: ScenarioSpec
    runs: int
    steps: tuple[str, ...]
    """What each kept candidate changed, in order."""
    violations: tuple[Violation, ...]
    """The kept scenario's violations (the original's when nothing was kept)."""


_Item = TypeVar("_Item")


def _without(items: tuple[_Item, ...], index: int) -> tuple[_Item, ...]:
    return items[:index] + items[index + 1 :]


def _towards(value: float, target: float, share: float, digits: int) -> float:
    return round(value + share * (target - value), digits)


def candidates(space: GeneratorSpace, base: Draw) -> Iterator[tuple[str, Draw]]:
    """Simpler draws than ``base``, simplest change first, each with what it changed."""
    for index, fault in enumerate(base.faults):
        yield (
            f"drop {fault.kind} (faults.{index})",
            replace(base, faults=_without(base.faults, index)),
        )
    for index, tsr in enumerate(base.tsrs):
        yield (
            f"drop TSR {index + 1} ({tsr.placement})",
            replace(base, tsrs=_without(base.tsrs, index)),
        )
    for index, ma in enumerate(base.mas):
        yield (
            f"drop MA shortening {index + 1} ({ma.placement})",
            replace(base, mas=_without(base.mas, index)),
        )
    if len(base.legs) > 1:
        last = len(base.legs) - 1
        yield (
            "drop the last leg",
            replace(
                base,
                legs=base.legs[:last],
                tsrs=tuple(t for t in base.tsrs if t.leg < last),
                mas=tuple(a for a in base.mas if a.leg < last),
            ),
        )
    targets = space.shrink_to
    for share, how in ((1.0, "to"), (0.5, "half way to")):
        if base.cap_kmh != targets.cap_kmh:
            cap = _towards(base.cap_kmh, targets.cap_kmh, share, 0)
            yield f"cap {how} {targets.cap_kmh:g} km/h", replace(base, cap_kmh=cap)
        legs = tuple(
            LegDraw(
                leg.stop_id,
                _towards(leg.slack, targets.slack, share, 3),
                _towards(leg.dwell_s, targets.dwell_s, share, 0),
            )
            for leg in base.legs
        )
        if legs != base.legs:
            yield f"slack and dwell {how} the library's", replace(base, legs=legs)
        if base.reaction_s != targets.reaction_s:
            reaction = _towards(base.reaction_s, targets.reaction_s, share, 1)
            yield f"reaction {how} {targets.reaction_s:g} s", replace(base, reaction_s=reaction)


def shrink(
    space: GeneratorSpace,
    base: Draw,
    invariant: InvariantName,
    run: RunJudge,
    *,
    max_runs: int = 12,
    violations: Sequence[Violation] = (),
) -> ShrinkResult:
    """The simplest draw found that still violates ``invariant``, within ``max_runs`` runs."""
    current, kept = base, tuple(violations)
    steps: list[str] = []
    runs = 0
    tried: set[Draw] = {base}
    progress = True
    while progress and runs < max_runs:
        progress = False
        for change, candidate in candidates(space, current):
            if candidate in tried:
                continue
            tried.add(candidate)
            if runs >= max_runs:
                break
            runs += 1
            found = tuple(run(render(space, candidate)))
            if any(v.invariant == invariant for v in found):
                current, kept = candidate, found
                steps.append(change)
                progress = True
                break
    shrunk = replace(current, suffix="-shrunk")
    return ShrinkResult(shrunk, render(space, shrunk), runs, tuple(steps), kept)
