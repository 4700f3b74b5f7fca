"""Quiet cycles: how Tasks B and C skip, in lockstep, the 2 ms cycles that cannot change them.

A cycle of Task B or C is a function of the task's state, of its inputs (queued messages, the
other task's status, the digital inputs) and of the simulated time; the time enters only through
comparisons ``now_s > threshold`` (deadlines, timeouts) and through the stamps of what the cycle
writes. When a full cycle consumed no input and left the task's state as it found it (a *fixed
point*), the next cycle with the same inputs, before any threshold not yet crossed is crossed,
is that same fixed point: it would only post the same status with a new ``time_s``. The task
then does just that, and runs its full cycle again at the first instant an input or a threshold
differs. :class:`QuietCycles` keeps the bookkeeping; each task defines its state's fingerprint,
its inputs and its thresholds (docs/vc.md, "Event-driven in lockstep").

Thresholds are written as the comparisons of the tasks write them (``a + b + TOLERANCE``), so
that ``now_s <= threshold`` is, float for float, the full cycle's "not yet".
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

from onboard.runtime import Executive
from onboard.runtime.clock import RealTimeClock

__all__ = ["QuietCycles", "skips_quiet_cycles"]


def skips_quiet_cycles(executive: Executive, event_driven: bool | None) -> bool:
    """Whether tasks registered on ``executive`` skip their quiet cycles: as asked, or by
    default in lockstep only (real time keeps the 2 ms cycle, its timing is what it measures)."""
    if event_driven is None:
        return not isinstance(executive.clock, RealTimeClock)
    return event_driven


class QuietCycles:
    """Whether a task's last full cycle was a fixed point, and until when it stays one."""

    __slots__ = ("enabled", "skipped", "until_s", "_fingerprint")

    def __init__(self) -> None:
        self.enabled = False
        """Skip quiet cycles (lockstep); off, every cycle is a full one (real time, tests)."""
        self.skipped = 0
        """Cycles skipped so far."""
        self.until_s = -math.inf
        """The cycle may be skipped while ``now_s <= until_s`` (and the inputs are unchanged)."""
        self._fingerprint: tuple[object, ...] | None = None

    def after_full_cycle(
        self,
        now_s: float,
        fingerprint: tuple[object, ...],
        *,
        took_input: bool,
        thresholds: Callable[[], Iterable[float]],
    ) -> None:
        """Note a full cycle at ``now_s``: its state's ``fingerprint`` afterwards, whether it
        consumed an input, and the thresholds of its ``now_s > threshold`` comparisons (asked
        for only after a fixed point)."""
        fixed = not took_input and fingerprint == self._fingerprint
        self._fingerprint = fingerprint
        if not fixed:
            self.until_s = -math.inf
            return
        # A threshold already crossed stays crossed: only those ahead can end the quiet.
        self.until_s = min((t for t in thresholds() if now_s <= t), default=math.inf)
