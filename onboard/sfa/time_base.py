"""The time base of the sensor packets (CONTRACT.md §3), for :class:`~onboard.sfa.ListenerCore`.

A sensor packet's epoch is the last STROBE timestamp plus k / rate, k counting that sensor's
packets since that STROBE. Under loss a plain count lags (lost packets are not counted, a lost
STROBE lets the lag grow), so k is the larger of the count and a conservative bound from the
SEQ_NO distance n to the STROBE, ⌊n · rate / N⌋ − 2, where N = 1 + Σ rates is the most packets
a second of sensor time can carry. Without loss the count is exact and the bound never exceeds
it (docs/sfa.md, "Time under loss"). A STROBE off the schedule of the last one (not the whole
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


class SensorTimeBase:
    """The STROBE the epochs count from, and each sensor's packets counted since it.

    Parameters
    ----------
    imu_rate_hz, odometer_rate_hz, gps_rate_hz : float
        The sensors' rates [Hz].
    """

    def __init__(self, *, imu_rate_hz: float, odometer_rate_hz: float, gps_rate_hz: float) -> None:
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

    def epoch(self, sensor_type: SensorType, seq_no: int) -> float:
        """The epoch [s] of a sensor packet, counted as that sensor's next since the STROBE."""
        count = self._since_strobe[sensor_type]
        period_s = self.periods_s[sensor_type]
        if self.strobe_seq is not None:
            distance = (seq_no - self.strobe_seq) % SEQ_MODULO
            bound = math.floor(distance / (period_s * self.packets_per_s)) - 2
            count = max(count, bound)
        self._since_strobe[sensor_type] = count + 1
        return self.strobe_s + count * period_s

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
