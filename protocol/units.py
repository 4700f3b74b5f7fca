"""Physical constants and the unit conversions the code needs, for every package.

SI inside the code (m, s, m/s, J); km/h and kWh only at the edges, in names that say so
(``speed_kmh``, ``traction_energy_kwh``). A speed written in km/h becomes m/s by
``speed_kmh * MPS_PER_KMH`` and goes back out by ``speed_mps / MPS_PER_KMH``; an energy goes out
in kWh by ``energy_j / J_PER_KWH``. They sit in ``protocol``, the package every other imports,
so that the onboard process, the track data and the trackside share one value
(docs/decisions.md, "One home for the vehicle's data and the physical constants").
"""

from __future__ import annotations

from typing import Final

__all__ = ["GRAVITY_MPS2", "J_PER_KWH", "MPS_PER_KMH"]

GRAVITY_MPS2: Final = 9.81
"""Standard gravity, rounded as the railway's resistance formulas use it [m/s²]."""

MPS_PER_KMH: Final = 1.0 / 3.6
"""One km/h in m/s."""

J_PER_KWH: Final = 3.6e6
"""One kWh in J: an energy in J is shown in kWh as ``energy_j / J_PER_KWH``."""
