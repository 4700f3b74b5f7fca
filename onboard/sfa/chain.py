"""The sensor-fusion chain inside the onboard node: what the ATO-OB and the ADF see of the train.

Every 10 ms tick of the node, right after the plant: the interface-modules' INPUT datagrams of
that tick (made by the sensor models of :mod:`onboard.plant`, which alone read the truth) go
through the (fault-injectable) link to the listener; the listener's OUTPUT datagrams reach the
OBCU's :class:`Localisation`, whose ACKs go back to the listener. Balise groups read by the BTM
are given to the filter as fixes. The chain is the same as the SFA bench's lockstep run, minus
the comparison with the truth, and is deterministic for a seed.

:attr:`position_m` and :attr:`speed_mps` are what the controller uses: the fused estimate
(``position_m`` unwrapped on a ring), with speeds under :data:`ZERO_SPEED_MPS` read as a
standstill, as an odometer's zero-speed detection does. Before the first estimate they are the
position the vehicle was started at (its stored position at power-up) and zero.
:attr:`localisation_valid` is the filter's health as the ATO-OB's "localised" condition needs it
(SUBSET-125: no localisation, no engagement).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from onboard.plant.sensors import SensorFaults, SensorNoise
from onboard.sfa.link import FaultyLink, LinkFaults
from onboard.sfa.listener import Health, ListenerConfig, ListenerCore
from onboard.sfa.localisation import Localisation, LocalisationEstimate
from trackdb import TrackMap

__all__ = [
    "BALISE_FIX_SIGMA_M",
    "LOCALISATION_MAX_SIGMA_M",
    "MARKER_FIX_SIGMA_M",
    "ZERO_SPEED_MPS",
    "SensorFusionChain",
    "SensorSettings",
]

ZERO_SPEED_MPS = 0.05
"""Fused speeds below this read as standstill [m/s] (0.18 km/h)."""
BALISE_FIX_SIGMA_M = 1.0
"""σ of a balise group's location as a fix [m]: the BTM's location error (σ ≤ 0.5 m, see
docs/sensors.md) and the group's surveyed location together."""
MARKER_FIX_SIGMA_M = 0.05
"""σ of a precision-stop marker's location as a fix [m]: the marker reader's error (σ 0.02 m,
docs/sensors.md) and the tag's surveyed location together."""
LOCALISATION_MAX_SIGMA_M = 5.0
"""⚠ Above this σ [m] the fused position is not good enough to drive on: localisation is not
valid (a stop must be made within ±0.5 m; 5 m is where the filter has clearly lost its aiding
sensors, well before the listener's own "degraded" threshold of 10 m)."""


@dataclass(frozen=True, kw_only=True)
class SensorSettings:
    """The emulated sensors, their link to the listener, and the seed of their randomness."""

    seed: int = 0
    noise: SensorNoise = field(default_factory=SensorNoise)
    faults: SensorFaults = field(default_factory=SensorFaults)
    link: LinkFaults = field(default_factory=LinkFaults)
    listener: ListenerConfig = field(default_factory=ListenerConfig)
    wheel_diameter_error: float | None = None
    """Calibrated over real wheel diameter minus 1 (+0.02 reads 2 % long); drawn from the seed
    (σ 0.2 %) when None. The axle-end sensors' (and so ETCS's and the VC's) scale error."""
    missed_balise_groups: frozenset[int] = frozenset()
    """Balise groups (NID_BG) the BTM fails to read (an injected fault)."""
    missed_stop_markers: frozenset[str] = frozenset()
    """Precision-stop markers (by id) the marker reader fails to read (an injected fault)."""


class SensorFusionChain:
    """Link → listener → OBCU localisation, stepped by the node with the sensors' datagrams.

    Parameters
    ----------
    track_map : TrackMap
        The onboard's track data.
    settings : SensorSettings
        The link's faults, the listener's configuration and the seed.
    start_position_m : float
        Where the vehicle was started [m] (its stored position): the first output is unwrapped
        near it on a ring, and it is the position until the first estimate.
    """

    def __init__(
        self,
        track_map: TrackMap,
        settings: SensorSettings = SensorSettings(),
        *,
        start_position_m: float = 0.0,
    ) -> None:
        self.track_map = track_map
        self.settings = settings
        self.link = FaultyLink(settings.link, np.random.default_rng([settings.seed, 1]))
        self.listener = ListenerCore(track_map, settings.listener)
        self.localisation = Localisation(track_map, listener=self.listener)
        self.localisation.expect_near(start_position_m)
        self._start_position_m = start_position_m

    def use_line(self, track_map: TrackMap) -> None:
        """New track data of the same line: the estimate (chainage, speed, biases) is kept and
        read on them from now on (gradients, GPS projection, the line's length)."""
        self.track_map = track_map
        self.listener.track_map = self.listener.filter.track_map = track_map
        self.localisation.track_map = track_map

    def step(self, now_s: float, datagrams: Iterable[bytes]) -> None:
        """One 10 ms tick: send the sensors' datagrams, deliver, fuse, acknowledge."""
        link, listener, localisation = self.link, self.listener, self.localisation
        for datagram in datagrams:
            link.send(datagram, now_s)
        for datagram, arrival_s in link.deliver(now_s):
            for output in listener.feed(datagram, arrival_s):
                localisation.receive(output, arrival_s)
        for output in listener.poll(now_s):
            localisation.receive(output, now_s)
        for ack in localisation.step(now_s):
            listener.on_ack(ack, now_s)

    def fix(
        self, chainage_m: float, detected_s: float, *, sigma_m: float = BALISE_FIX_SIGMA_M
    ) -> None:
        """A point of the track located at ``detected_s`` [s], at its chainage on the line [m],
        with σ ``sigma_m`` [m] (a balise group read by the BTM by default). The fix is taken at
        the filter's epoch, moved by the estimated speed over the time between (the filter may
        run a little behind or ahead of the detection)."""
        flt = self.listener.filter
        epoch_s = flt.epoch_s if flt.initialised else detected_s
        fix_m = self.track_map.normalise(chainage_m + (epoch_s - detected_s) * self.speed_mps)
        self.localisation.fix(fix_m, sigma_m, epoch_s)

    @property
    def estimate(self) -> LocalisationEstimate | None:
        return self.localisation.estimate

    @property
    def position_m(self) -> float:
        estimate = self.localisation.estimate
        return self._start_position_m if estimate is None else estimate.position_m

    @property
    def speed_mps(self) -> float:
        estimate = self.localisation.estimate
        if estimate is None or abs(estimate.speed_mps) < ZERO_SPEED_MPS:
            return 0.0
        return estimate.speed_mps

    @property
    def acceleration_mps2(self) -> float:
        """The filter's acceleration: the IMU's input less its estimated bias [m/s²]."""
        flt = self.listener.filter
        if not flt.initialised:
            return 0.0
        return flt.last_input_mps2 - flt.bias_mps2

    @property
    def sigma_m(self) -> float | None:
        estimate = self.localisation.estimate
        return None if estimate is None else estimate.sigma_m

    @property
    def localisation_valid(self) -> bool:
        """An estimate, not lost (the IMU or the odometer alive, outputs fresh), and σ within
        :data:`LOCALISATION_MAX_SIGMA_M`."""
        estimate = self.localisation.estimate
        return (
            estimate is not None
            and estimate.health is not Health.LOST
            and estimate.sigma_m <= LOCALISATION_MAX_SIGMA_M
        )
