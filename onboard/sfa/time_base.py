"""The time base of the sensor packets (CONTRACT.md §3), for :class:`~onboard.sfa.ListenerCore`.

A sensor packet's epoch is the last STROBE timestamp plus k / rate, k counting that sensor's
packets since that STROBE. Under loss a plain count lags (lost packets are not counted, a lost
STROBE lets the lag grow), so k is the larger of the count and a conservative bound from the
SEQ_NO distance n to the STROBE, ⌊n · rate / N⌋ − 2, where N = 1 + Σ rates is the most packets
a second of sensor time can carry. Without loss the count is exact and the bound never exceeds
it (docs/sfa.md, "Time under loss"). Nor may a packet be earlier than one before it in SEQ_NO
order, less ``order_tolerance_s``: a sensor of a low rate (the 1 Hz GPS) whose packet and the
STROBE before it are both lost would otherwise count its next packet as the first of the older
second, a whole period early, as no SEQ_NO bound can tell one second from the next for it. A
STROBE off the schedule of the last one (not the whole
number of seconds after it that its SEQ_NO distance spans) sets the time base only once the
next STROBE confirms it: one corrupted byte of its time would otherwise move every epoch of its
second.
"""

from __future__ import annotations

import math

from onboard.sfa.status import (
    MAX_STROBE_BACKWARDS_S,
    MAX_STROBE_GAP_S,
    STROBE_PERIOD_S,
    STROBE_TOLERANCE_S,
)
from protocol.udp import SEQ_MODULO, SensorType

__all__ = ["SensorTimeBase"]

_GRID_EPSILON = 1e-9
"""Periods within this of a grid point count as on it (rounding of the epochs' sums)."""


class SensorTimeBase:
    """The STROBE the epochs count from, and each sensor's packets counted since it.

    Parameters
    ----------
    imu_rate_hz, odometer_rate_hz, gps_rate_hz : float
        The sensors' rates [Hz].
    order_tolerance_s : float
        How far an epoch may lie ahead of its packet's true time [s]: a SEQ_NO corrupted a few
        numbers ahead is released in its place (the reorder buffer's ``max_wait_s`` of
        packets), and its epoch with it. A packet's epoch is at least the latest given since
        the STROBE less this.
    """

    def __init__(
        self,
        *,
        imu_rate_hz: float,
        odometer_rate_hz: float,
        gps_rate_hz: float,
        order_tolerance_s: float = 0.05,
    ) -> None:
        self.periods_s = {
            SensorType.IMU: 1.0 / imu_rate_hz,
            SensorType.ODOMETER: 1.0 / odometer_rate_hz,
            SensorType.GPS: 1.0 / gps_rate_hz,
        }
        self.packets_per_s = 1.0 + sum(1.0 / period for period in self.periods_s.values())
        """N: the most packets a second of sensor time can carry."""
        self.strobe_s = 0.0
        self.strobe_seq: int | None = None
        self.rebase_pending = True
        """A GROUND_TRUTH (re)started the run: the next STROBE sets the time base, whatever its
        time."""
        self._strobe_candidate: tuple[float, int] | None = None
        """(time, SEQ_NO) of the last STROBE dropped as off schedule: the next STROBE on its
        schedule confirms the new time base."""
        self._since_strobe = {SensorType.IMU: 0, SensorType.ODOMETER: 0, SensorType.GPS: 0}
        self.order_tolerance_s = order_tolerance_s
        self._latest_s = 0.0
        """The latest epoch given since the STROBE [s]."""

    def epoch(self, sensor_type: SensorType, seq_no: int) -> float:
        """The epoch [s] of a sensor packet, counted as that sensor's next since the STROBE."""
        count = self._since_strobe[sensor_type]
        period_s = self.periods_s[sensor_type]
        if self.strobe_seq is not None:
            distance = (seq_no - self.strobe_seq) % SEQ_MODULO
            bound = math.floor(distance / (period_s * self.packets_per_s)) - 2
            count = max(count, bound)
        # Sent after the packets before it: not earlier than the latest epoch, on its own grid.
        ahead_s = self._latest_s - self.order_tolerance_s - self.strobe_s
        after = math.ceil(ahead_s / period_s - _GRID_EPSILON)
        count = max(count, after)
        self._since_strobe[sensor_type] = count + 1
        epoch_s = self.strobe_s + count * period_s
        self._latest_s = max(self._latest_s, epoch_s)
        return epoch_s

    def strobe(self, strobe_s: float, seq_no: int) -> str | None:
        """A STROBE at ``strobe_s`` [s]: None when it sets the time base, else the reason it is
        dropped (``invalid_value``, ``strobe_unconfirmed``)."""
        if not self.rebase_pending:
            refused = self._refusal(strobe_s, seq_no)
            if refused is not None:
                return refused
        self.rebase_pending = False
        self.strobe_s = strobe_s
        self.strobe_seq = seq_no
        self._strobe_candidate = None
        self._latest_s = strobe_s
        for key in self._since_strobe:
            self._since_strobe[key] = 0
        return None

    def rebase(self) -> None:
        """A GROUND_TRUTH: the next STROBE sets the time base of the new run."""
        self.rebase_pending = True
        self._strobe_candidate = None

    def _on_schedule(self, strobe_s: float, seq_no: int, reference: tuple[float, int]) -> bool:
        """Whether a STROBE lies a whole number of periods after the ``reference`` STROBE (time,
        SEQ_NO), that number being the periods its SEQ_NO distance spans at the full rate (at
        least one: a sender with sensors silent sends fewer packets a second)."""
        reference_s, reference_seq = reference
        periods = max(1, round((seq_no - reference_seq) % SEQ_MODULO / self.packets_per_s))
        return abs(strobe_s - reference_s - periods * STROBE_PERIOD_S) <= STROBE_TOLERANCE_S

    def _refusal(self, strobe_s: float, seq_no: int) -> str | None:
        """Why a STROBE may not set the time base; None when it may.

        Beyond 1 s backwards or 600 s forwards it is ``invalid_value``. Off the schedule of the
        last STROBE (a corrupted time, which a single byte makes anything up to that, or a
        sender whose clock stepped) it is ``strobe_unconfirmed`` and remembered: the next
        STROBE on the schedule of the remembered one confirms the new time base, the next on
        the old schedule refutes it. Until then the epochs run on from the last STROBE, as when
        a STROBE is lost."""
        if not (
            self.strobe_s - MAX_STROBE_BACKWARDS_S <= strobe_s <= self.strobe_s + MAX_STROBE_GAP_S
        ):
            return "invalid_value"
        assert self.strobe_seq is not None  # a STROBE has set the base
        if self._on_schedule(strobe_s, seq_no, (self.strobe_s, self.strobe_seq)):
            return None
        candidate, self._strobe_candidate = self._strobe_candidate, (strobe_s, seq_no)
        if candidate is not None and self._on_schedule(strobe_s, seq_no, candidate):
            return None
        return "strobe_unconfirmed"
