"""The sensor-fusion chain inside the onboard node: what the ATO-OB and the ADF see of the train.

Every 10 ms tick of the node, right after the plant: the interface-modules emulator turns the
plant's truth into INPUT datagrams, which go through the (fault-injectable) link to the
listener; the listener's OUTPUT datagrams reach the OBCU's :class:`Localisation`, whose ACKs go
back to the listener. Balise groups read by ETCS are given to the filter as fixes. The chain
is the same as :func:`onboard.sfa.lockstep.run_lockstep`'s, minus the comparison with the truth,
and is deterministic for a seed.

:attr:`position_m` and :attr:`speed_mps` are what the controller uses: the fused estimate
(``position_m`` unwrapped like the plant's), with speeds under :data:`ZERO_SPEED_MPS` read as a
standstill, as an odometer's zero-speed detection does. Before the first estimate (the first
tick) they are the GROUND_TRUTH the interface-modules start with.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from onboard.plant.interfaces import BogieTruth
from onboard.plant.sensors import (
    InterfaceModules,
    SensorFaults,
    SensorNoise,
    TruthSample,
    truth_from_bogie,
)
from onboard.sfa.link import FaultyLink, LinkFaults
from onboard.sfa.listener import ListenerConfig, ListenerCore
from onboard.sfa.localisation import Localisation, LocalisationEstimate
from trackdb import TrackMap

__all__ = ["BALISE_FIX_SIGMA_M", "ZERO_SPEED_MPS", "SensorFusionChain", "SensorSettings"]

ZERO_SPEED_MPS = 0.05
"""Fused speeds below this read as standstill [m/s] (0.18 km/h)."""
BALISE_FIX_SIGMA_M = 1.0
"""σ of a balise group's location as a fix [m] (the group's location accuracy is ±5 m at worst;
the reading itself is far better)."""


@dataclass(frozen=True, kw_only=True)
class SensorSettings:
    """The emulated sensors, their link to the listener, and the seed of their randomness."""

    seed: int = 0
    noise: SensorNoise = field(default_factory=SensorNoise)
    faults: SensorFaults = field(default_factory=SensorFaults)
    link: LinkFaults = field(default_factory=LinkFaults)
    listener: ListenerConfig = field(default_factory=ListenerConfig)


class SensorFusionChain:
    """Interface-modules → link → listener → OBCU localisation, stepped by the node."""

    def __init__(self, track_map: TrackMap, settings: SensorSettings = SensorSettings()) -> None:
        self.track_map = track_map
        self.settings = settings
        rng = np.random.default_rng(settings.seed)
        self.modules = InterfaceModules(track_map, rng=rng, noise=settings.noise,
                                        faults=settings.faults)  # fmt: skip
        self.link = FaultyLink(settings.link, rng)
        self.listener = ListenerCore(track_map, settings.listener)
        self.localisation = Localisation(track_map, listener=self.listener)
        self._started = False
        self._start_position_m = 0.0

    @staticmethod
    def truth(now_s: float, plant: object) -> TruthSample:
        """The plant's truth at ``now_s``, with the wheel's speed when the bogie model runs."""
        bogie = getattr(plant, "truth", None)
        if isinstance(bogie, BogieTruth):
            return truth_from_bogie(bogie)
        return TruthSample(
            time_s=now_s, position_m=plant.position_m, speed_mps=plant.speed_mps,  # type: ignore[attr-defined]
            acceleration_mps2=plant.acceleration_mps2,  # type: ignore[attr-defined]
        )  # fmt: skip

    def step(self, now_s: float, truth: TruthSample) -> None:
        """One 10 ms tick: send, deliver, fuse, acknowledge."""
        link, listener, localisation = self.link, self.listener, self.localisation
        if not self._started:
            self._started = True
            self._start_position_m = truth.position_m
            self.localisation.expect_near(truth.position_m)
            for datagram in self.modules.start(truth):
                link.send(datagram, now_s)
        for datagram in self.modules.step(truth):
            link.send(datagram, now_s)
        for datagram, arrival_s in link.deliver(now_s):
            for output in listener.feed(datagram, arrival_s):
                localisation.receive(output, arrival_s)
        for output in listener.poll(now_s):
            localisation.receive(output, now_s)
        for ack in localisation.step(now_s):
            listener.on_ack(ack, now_s)

    def fix(self, chainage_m: float, now_s: float) -> None:
        """A balise group read by ETCS at ``now_s``, at its chainage on the line."""
        self.localisation.fix(self.track_map.normalise(chainage_m), BALISE_FIX_SIGMA_M, now_s)

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
    def sigma_m(self) -> float | None:
        estimate = self.localisation.estimate
        return None if estimate is None else estimate.sigma_m
