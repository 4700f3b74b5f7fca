"""What supervising the speed on the sensor-fusion estimate would gain (issue 7, item 5).

With ETCS isolated the VC brakes above 30 km/h (condition 6) on its tachometer speed: a mean
over the board's 80 ms frames, so a crossing of the limit is seen 40 to 120 ms late (scenario L:
80 ms data + 450 ms pipe, 536 ms in the seeds). The sensor-fusion listener publishes a speed
at every IMU packet (100 Hz); ``VcConfig.fused_speed_supervision`` makes Task B supervise the
larger of the two, the fused one with a margin of about two standard deviations of its error.
It can only brake sooner than the tachometer alone, never later.

:func:`compare_fused_speed` runs the odometry-driven scenarios of the catalogue with and without
the option, the fused error drawn from several seeds (a first-order Gauss–Markov error, 0.05 m/s,
1 s correlation: a Kalman filter's error drifts, it is not white), and
:func:`format_fused_comparison` prints hazard → EB command and hazard → full EB side by side.
A negative time is an EB commanded before the true speed reached the limit.
"""

from __future__ import annotations

import dataclasses
import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from deploy.bench.vc_catalogue import scenario
from deploy.bench.vc_runner import ScenarioResult, run_scenario
from deploy.bench.vc_scenarios import Scenario

__all__ = [
    "FUSED_COMPARISON_KEYS",
    "FusedComparison",
    "compare_fused_speed",
    "format_fused_comparison",
    "with_fused_speed",
]

FUSED_COMPARISON_KEYS = ("L", "M", "M-silent", "M-noisy", "isolated-28kmh")
"""The scenarios where the VC supervises the odometry itself (ETCS isolated)."""


def with_fused_speed(base: Scenario) -> Scenario:
    """``base`` with the speed supervised on the fused speed as well."""
    config = dataclasses.replace(base.config, fused_speed_supervision=True)
    return dataclasses.replace(base, key=f"{base.key}+fused", config=config)


@dataclass(frozen=True)
class FusedComparison:
    """One scenario with the tachometer alone, and with the fused speed under each seed."""

    key: str
    tachometer: ScenarioResult
    fused: tuple[ScenarioResult, ...]

    def fused_values(self, attribute: str) -> list[float]:
        values = (getattr(result, attribute) for result in self.fused)
        return [value for value in values if value is not None]


def compare_fused_speed(
    keys: Iterable[str] = FUSED_COMPARISON_KEYS, seeds: Iterable[int] = range(20)
) -> tuple[FusedComparison, ...]:
    """Run each scenario without the option, then with it once per seed."""
    seeds = tuple(seeds)
    comparisons = []
    for key in keys:
        base = scenario(key)
        fused = with_fused_speed(base)
        comparisons.append(
            FusedComparison(
                key=key,
                tachometer=run_scenario(base),
                fused=tuple(run_scenario(fused, seed=seed) for seed in seeds),
            )
        )
    return tuple(comparisons)


def _ms(value: float | None) -> str:
    return "—" if value is None else f"{value * 1000:.0f}"


def _spread(values: Sequence[float]) -> str:
    if not values:
        return "—"
    return (
        f"{min(values) * 1000:.0f} / {statistics.median(values) * 1000:.0f} / "
        f"{max(values) * 1000:.0f}"
    )


def format_fused_comparison(comparisons: Sequence[FusedComparison]) -> str:
    """A table: outcome and timings with the tachometer alone, and with the fused speed
    (min / median / max over the seeds)."""
    lines = [
        "Speed supervision with ETCS isolated: tachometer alone vs. with the fused speed "
        "(hazard = the true speed crossing 30 km/h; min / median / max over the seeds)",
        f"{'scenario':<16}{'class':<19}{'haz→EB':>8}{'haz→full':>10}   "
        f"{'fused: class':<22}{'haz→EB [ms]':>18}{'haz→full [ms]':>18}",
    ]
    for item in comparisons:
        base = item.tachometer
        classes = sorted({result.outcome.value for result in item.fused})
        lines.append(
            f"{item.key:<16}{base.outcome.value:<19}{_ms(base.hazard_to_eb_command_s):>8}"
            f"{_ms(base.hazard_to_full_eb_s):>10}   {', '.join(classes):<22}"
            f"{_spread(item.fused_values('hazard_to_eb_command_s')):>18}"
            f"{_spread(item.fused_values('hazard_to_full_eb_s')):>18}"
        )
    return "\n".join(lines)
