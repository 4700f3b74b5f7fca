"""The OBCU side of seed 002: the onboard localisation input.

:class:`Localisation` consumes OUTPUT_PROTOCOL datagrams (any order: the newest EPOCH wins, as
seed 002 §3.2.2 allows), answers with an ACK of the last SEQ_NO received once a second, and
exposes :attr:`Localisation.estimate` to the onboard node: chainage on the line, the position
unwrapped across laps of a ring, speed, σ, health and which sensors are alive.

OUTPUT_PROTOCOL carries only (SEQ_NO, EPOCH, chainage). When the listener runs in the same
process (the architecture's case) the :class:`Localisation` is given its
:class:`~onboard.sfa.listener.ListenerCore` and reads speed, σ and sensor health from the
listener's status; balise-group fixes then go into the filter. Without one (a remote listener)
speed is differenced from successive outputs, σ is ``nominal_sigma_m`` and a fix shifts the
published position by the fix's residual.

It opens no socket and reads no clock: ``receive`` and ``step`` take the time.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

from onboard.sfa.filter import check_fix, unwrap_near
from onboard.sfa.listener import Health, ListenerCore
from protocol import MalformedDatagramError
from protocol.udp import Ack, decode_output, encode_ack
from trackdb import TrackMap

__all__ = ["MAX_EXTRAPOLATION_S", "Localisation", "LocalisationEstimate"]

MAX_EXTRAPOLATION_S = 3.0
"""Longest extrapolation of the newest output to the present [s]."""


@dataclass(frozen=True, slots=True)
class LocalisationEstimate:
    """What the onboard node sees of the train's location (SI units)."""

    epoch_s: float
    """Epoch [s] of the newest OUTPUT datagram."""
    chainage_m: float
    """Chainage on the line [m], wrapped on a ring, extrapolated to the last ``step``."""
    position_m: float
    """Unwrapped position [m]: on a ring it keeps counting past the origin."""
    speed_mps: float
    sigma_m: float
    health: Health
    imu_alive: bool | None
    odometer_alive: bool | None
    gps_alive: bool | None
    """Sensor health; None when no listener is attached (a remote listener)."""


class Localisation:
    """The onboard localisation input: OUTPUT datagrams in, ACKs out, an estimate exposed.

    Parameters
    ----------
    track_map : TrackMap
        The line (to wrap and unwrap chainages).
    listener : ListenerCore, optional
        The in-process listener whose status gives speed, σ and sensor health.
    ack_period_s : float
        Interval between ACKs [s].
    stale_after_s : float
        Without a newer output for this long the health is lost [s].
    nominal_sigma_m : float
        σ reported when no listener is attached [m].
    """

    def __init__(
        self,
        track_map: TrackMap,
        *,
        listener: ListenerCore | None = None,
        ack_period_s: float = 1.0,
        stale_after_s: float = 1.0,
        nominal_sigma_m: float = 5.0,
    ) -> None:
        self.track_map = track_map
        self.listener = listener
        self.ack_period_s = ack_period_s
        self.stale_after_s = stale_after_s
        self.nominal_sigma_m = nominal_sigma_m
        self.counters: Counter[str] = Counter()
        self.estimate: LocalisationEstimate | None = None
        self._last_seq: int | None = None
        self._newest_epoch_s = -math.inf
        self._newest_arrival_s = -math.inf
        self._position_m: float | None = None
        self._expected_m: float | None = None
        self._speed_mps = 0.0
        self._offset_m = 0.0
        self._next_ack_s: float | None = None

    def receive(self, datagram: bytes, arrival_s: float) -> None:
        """Take one OUTPUT datagram arrived at ``arrival_s`` [s]; bad ones are counted."""
        try:
            packet = decode_output(datagram)
        except MalformedDatagramError:
            self.counters["malformed"] += 1
            return
        self.counters["received"] += 1
        self._last_seq = packet.seq_no
        chainage_m = packet.arc_length_km * 1000.0
        if not (math.isfinite(packet.epoch_s) and math.isfinite(chainage_m)):
            self.counters["non_finite"] += 1
            return
        restarted = arrival_s - self._newest_arrival_s > self.stale_after_s
        if packet.epoch_s <= self._newest_epoch_s and not restarted:
            self.counters["older"] += 1
            return
        if restarted and packet.epoch_s <= self._newest_epoch_s:
            # After a silence the listener may have restarted its time base: follow it.
            self.counters["resynchronised"] += 1
            self._newest_epoch_s = -math.inf
        previous_epoch_s, previous_position_m = self._newest_epoch_s, self._position_m
        self._position_m = self._unwrap(chainage_m)
        if previous_position_m is not None and packet.epoch_s - previous_epoch_s > 1e-3:
            self._speed_mps = (self._position_m - previous_position_m) / (
                packet.epoch_s - previous_epoch_s
            )
        self._newest_epoch_s = packet.epoch_s
        self._newest_arrival_s = arrival_s
        if self._next_ack_s is None:
            self._next_ack_s = arrival_s

    def expect_near(self, position_m: float) -> None:
        """Where the train stands before the first output (the GROUND_TRUTH it started from):
        on a ring, the first chainage is unwrapped to the lap nearest this, so that a start at
        chainage 0 that reads a little behind it is not taken for the end of the lap."""
        self._expected_m = position_m

    def _unwrap(self, chainage_m: float) -> float:
        if self._position_m is None:
            if self._expected_m is None:
                return chainage_m
            return unwrap_near(self.track_map, chainage_m, self._expected_m)
        return unwrap_near(self.track_map, chainage_m, self._position_m)

    def step(self, now_s: float) -> list[bytes]:
        """Refresh :attr:`estimate` for ``now_s`` [s]; returns the ACK datagrams now due."""
        acks: list[bytes] = []
        due_s = self._next_ack_s
        if due_s is not None and self._last_seq is not None and now_s >= due_s:
            acks.append(encode_ack(Ack(self._last_seq)))
            self.counters["acks_sent"] += 1
            self._next_ack_s = max(due_s + self.ack_period_s, now_s - self.ack_period_s)
        self._refresh(now_s)
        return acks

    def _refresh(self, now_s: float) -> None:
        if self._position_m is None:
            return
        status = self.listener.status if self.listener is not None else None
        speed_mps = status.speed_mps if status is not None else self._speed_mps
        sigma_m = status.sigma_m if status is not None else self.nominal_sigma_m
        health = status.health if status is not None else Health.OK
        # Extrapolate from the newest epoch to now, bounded: a dead listener must not push the
        # estimate along for ever (its health says lost by then).
        age_s = min(max(now_s - self._newest_epoch_s, 0.0), MAX_EXTRAPOLATION_S)
        position_m = self._position_m + self._offset_m + speed_mps * age_s
        if now_s - self._newest_arrival_s > self.stale_after_s:
            health = Health.LOST
        self.estimate = LocalisationEstimate(
            epoch_s=self._newest_epoch_s,
            chainage_m=self.track_map.normalise(position_m),
            position_m=position_m,
            speed_mps=speed_mps,
            sigma_m=sigma_m,
            health=health,
            imu_alive=None if status is None else status.imu_alive,
            odometer_alive=None if status is None else status.odometer_alive,
            gps_alive=None if status is None else status.gps_alive,
        )

    def fix(self, chainage_m: float, sigma_m: float, epoch_s: float) -> None:
        """A balise-group fix: chainage on the line [m], its σ [m], at ``epoch_s`` [s].

        With an attached listener the fix goes into the filter; otherwise the published
        position is shifted by the fix's residual.

        Raises
        ------
        ValueError
            If a value is not finite or σ is not positive.
        """
        check_fix(chainage_m, sigma_m, epoch_s)
        self.counters["fixes"] += 1
        if self.listener is not None and self.listener.filter.initialised:
            self.listener.fix(chainage_m, sigma_m, epoch_s)
            return
        if self._position_m is None:
            return
        current = self._position_m + self._offset_m
        self._offset_m += unwrap_near(self.track_map, chainage_m, current) - current
