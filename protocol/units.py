"""Physical constants and the one unit conversion the code needs, for every package.

SI inside the code (m, s, m/s); km/h only at the edges, in names that say so (``speed_kmh``).
A speed written in km/h becomes m/s by ``speed_kmh * MPS_PER_KMH`` and goes back out by
``speed_mps / MPS_PER_KMH``. It sits in ``protocol``, the package every other imports, so that
the onboard process, the track data and the trackside share one value (docs/decisions.md,
"One home for the vehicle's data and the physical constants").
"""

from __future__ import annotations

from typing import Final

__all__ = ["GRAVITY_MPS2", "MPS_PER_KMH"]

GRAVITY_MPS2: Final = 9.81
"""Standard gravity, rounded as the railway's resistance formulas use it [m/s²]."""

MPS_PER_KMH: Final = 1.0 / 3.6
"""One km/h in m/s."""
