"""The one percentile of the KPIs, the campaigns and the benches.

Every distribution the project reports (a run's NMPC solve times in ``kpis.json``, a campaign's
KPIs, each bench's latencies) goes through :func:`percentiles`, so that a "p99" means the same
thing everywhere: numpy's ``linear`` interpolation between the two nearest order statistics
(Hyndman and Fan's type 7, numpy's and R's default), which is what ``kpis.json`` always used.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

import numpy as np
import numpy.typing as npt

__all__ = ["PERCENTILE_METHOD", "percentiles"]

PERCENTILE_METHOD: Final = "linear"
"""numpy's interpolation between order statistics; ``np.percentile``'s default."""


def percentiles(samples: npt.ArrayLike, qs: Sequence[float]) -> tuple[float, ...]:
    """The ``qs`` percentiles of ``samples``, in the order of ``qs``.

    Parameters
    ----------
    samples : array_like, shape (n,)
        The sample, in any unit and any order; ``n >= 1``.
    qs : sequence of float
        Percentiles in [0, 100] (50 is the median, 100 the maximum).

    Returns
    -------
    tuple of float
        One value per percentile, in the samples' unit.

    Raises
    ------
    ValueError
        When there is no sample or a percentile is outside [0, 100].
    """
    values = np.asarray(samples, dtype=np.float64)
    if values.size == 0:
        raise ValueError("percentiles of no sample")
    if not all(0.0 <= q <= 100.0 for q in qs):
        raise ValueError(f"percentiles must lie in [0, 100], got {tuple(qs)}")
    found = np.percentile(values, np.asarray(qs, dtype=np.float64), method=PERCENTILE_METHOD)
    return tuple(float(value) for value in found)
