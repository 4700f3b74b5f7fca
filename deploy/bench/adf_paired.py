"""Our NMPC and IPOPT on the very same NLPs, in turn at each control step of one lap: issue
24's "p99 at least 10× below IPOPT's on the same problem in the same run".

Two laps, one a solver, solve problems that differ by what each solver's own answers made of
the lap, minutes apart on a machine whose load drifts. Here our configuration drives the lap
and, at each step, IPOPT solves the same problem beside it (the same measured state,
reference and last demand; its answer is discarded), the two taking turns at going first: a
burst of load falls on both alike. Each solve's processor time (``time.thread_time``) is kept
beside its wall time: on a shared machine the wall time's tail is the scheduler's (a solve
preempted for a time slice), the processor time's is the solver's.
"""

from __future__ import annotations

import time
from typing import Any

from onboard.adf.nmpc import NmpcConfig, NmpcController, NmpcReference, NmpcResult, NmpcStats
from onboard.plant.point_mass import PointMassParameters

__all__ = ["PairedController"]


class PairedController(NmpcController):
    """Our NMPC (``sqpmethod``), which drives, with IPOPT solving each of its problems."""

    def __init__(self, model: PointMassParameters) -> None:
        super().__init__(model, NmpcConfig(solver="sqpmethod"))
        self.ipopt = NmpcController(model, NmpcConfig(solver="ipopt"))
        self._ipopt_first = False
        self.cpu_times_s: list[float] = []
        """Processor time of each of our solves [s]."""
        self.ipopt_cpu_times_s: list[float] = []

    @property
    def ipopt_stats(self) -> NmpcStats:
        return self.ipopt.stats

    def reset(self) -> None:
        super().reset()
        self.ipopt.reset()

    def solve(
        self,
        *,
        position_m: float,
        speed_mps: float,
        applied_force_n: float,
        reference: NmpcReference,
    ) -> NmpcResult:
        """Our solve, whose result is applied, and IPOPT's on the same problem, before or
        after it by turns."""
        demand_n = self._demand_n
        self._ipopt_first = not self._ipopt_first
        measured: dict[str, Any] = {
            "position_m": position_m,
            "speed_mps": speed_mps,
            "applied_force_n": applied_force_n,
            "reference": reference,
        }
        if self._ipopt_first:
            self._ipopt_solve(demand_n, measured)
        started = time.thread_time()
        result = super().solve(**measured)
        self.cpu_times_s.append(time.thread_time() - started)
        if not self._ipopt_first:
            self._ipopt_solve(demand_n, measured)
        return result

    def _ipopt_solve(self, demand_n: float | None, measured: dict[str, Any]) -> None:
        # The same NLP: IPOPT's demand starts from the one our controller last sent.
        self.ipopt._demand_n = demand_n
        started = time.thread_time()
        self.ipopt.solve(**measured)
        self.ipopt_cpu_times_s.append(time.thread_time() - started)
