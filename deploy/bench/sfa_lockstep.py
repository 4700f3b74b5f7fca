"""The sensor-fusion chain in lockstep, without sockets: plant → interface-modules → link →
listener → Localisation → ACKs, every 10 ms of simulated time, deterministic for a seed.

Each tick: the plant steps; the interface-modules send that tick's datagrams into the
:class:`~onboard.sfa.link.FaultyLink`; what the link delivers by the tick is fed to the
:class:`~onboard.sfa.listener.ListenerCore` at its delivery time; the listener's OUTPUT
datagrams go to the :class:`~onboard.sfa.localisation.Localisation`, whose ACKs come back to the
listener. The estimate at each tick is compared with the truth at that tick.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from deploy.bench.sfa_drive import DriveSettings, SpeedProfileDrive
from deploy.bench.sfa_recording import Recording
from onboard.plant.sensors import InterfaceModules, TimeWindow, TruthSample
from onboard.sfa.link import FaultyLink
from onboard.sfa.listener import Health, ListenerCore
from onboard.sfa.localisation import Localisation, LocalisationEstimate
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap, load_seed_line

__all__ = ["DriveResult", "DriveSettings", "ErrorStats", "run_lockstep"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ErrorStats:
    """Along-track position [m] and speed [km/h] errors over a set of instants."""

    samples: int
    position_rms_m: float
    position_max_m: float
    speed_rms_kmh: float

    @classmethod
    def of(cls, position_errors_m: FloatArray, speed_errors_mps: FloatArray) -> ErrorStats:
        if position_errors_m.size == 0:
            return cls(0, float("nan"), float("nan"), float("nan"))
        return cls(
            samples=int(position_errors_m.size),
            position_rms_m=float(np.sqrt(np.mean(position_errors_m**2))),
            position_max_m=float(np.max(np.abs(position_errors_m))),
            speed_rms_kmh=float(np.sqrt(np.mean(speed_errors_mps**2)) / MPS_PER_KMH),
        )


@dataclass
class DriveResult:
    """Per-tick errors of a lockstep drive and what every part counted."""

    settings: DriveSettings
    times_s: FloatArray
    position_errors_m: FloatArray
    speed_errors_mps: FloatArray
    odometer_alive: npt.NDArray[np.bool_]
    lost: npt.NDArray[np.bool_]
    """Whether the Localisation's health was lost at each tick."""
    listener: ListenerCore
    localisation: Localisation
    link: FaultyLink
    recording: Recording | None

    def stats(self, window: TimeWindow | None = None) -> ErrorStats:
        """Error statistics over the whole drive, or over a window of it."""
        if window is None:
            mask = np.ones(self.times_s.shape, dtype=bool)
        else:
            mask = (self.times_s >= window.start_s) & (self.times_s < window.end_s)
        return ErrorStats.of(self.position_errors_m[mask], self.speed_errors_mps[mask])

    def detection_delay_s(self, failure_s: float) -> float | None:
        """Time [s] from a sensor failure at ``failure_s`` until the odometer is reported
        failed; None if it never is."""
        after = (self.times_s >= failure_s) & ~self.odometer_alive
        if not after.any():
            return None
        return float(self.times_s[np.argmax(after)] - failure_s)


def run_lockstep(settings: DriveSettings, track_map: TrackMap | None = None) -> DriveResult:
    """Drive, emulate, fuse and compare, tick by tick (10 ms)."""
    track_map = track_map or TrackMap(load_seed_line(settings.line_id))
    rng = np.random.default_rng(settings.seed)
    drive = SpeedProfileDrive(track_map, start_m=settings.start_m, cruise_kmh=settings.cruise_kmh)
    chain = _Chain.build(track_map, settings, rng)
    errors = _TickErrors.sized(round(settings.duration_s / drive.dt_s) + 1)
    truths = drive.run(settings.duration_s)
    first = next(truths)
    for datagram in chain.modules.start(first):
        chain.link.send(datagram, first.time_s)
    for truth in itertools.chain([first], truths):
        chain.tick(truth)
        estimate = chain.localisation.estimate
        if estimate is not None:
            errors.add(truth, estimate)
    for datagram in chain.modules.stop():
        chain.link.send(datagram, drive.time_s)
    chain.deliver(float("inf"))
    count = errors.count
    return DriveResult(
        settings=settings,
        times_s=errors.times_s[:count],
        position_errors_m=errors.position_errors_m[:count],
        speed_errors_mps=errors.speed_errors_mps[:count],
        odometer_alive=errors.odometer_alive[:count],
        lost=errors.lost[:count],
        listener=chain.listener,
        localisation=chain.localisation,
        link=chain.link,
        recording=chain.recording,
    )


@dataclass
class _Chain:
    """Interface-modules → link → listener → Localisation, and the recording if asked for."""

    modules: InterfaceModules
    link: FaultyLink
    listener: ListenerCore
    localisation: Localisation
    recording: Recording | None

    @classmethod
    def build(
        cls, track_map: TrackMap, settings: DriveSettings, rng: np.random.Generator
    ) -> _Chain:
        modules = InterfaceModules(
            track_map, rng=rng, noise=settings.noise, faults=settings.sensor_faults
        )
        link = FaultyLink(settings.link_faults, rng)
        listener = ListenerCore(track_map, settings.listener)
        localisation = Localisation(track_map, listener=listener)
        recording = Recording.empty(settings.line_id) if settings.record else None
        return cls(modules, link, listener, localisation, recording)

    def deliver(self, now_s: float) -> None:
        """Feed the listener what the link delivers by ``now_s``, each at its arrival time."""
        for datagram, arrival_s in self.link.deliver(now_s):
            if self.recording is not None:
                self.recording.add_datagram(datagram, arrival_s)
            for output in self.listener.feed(datagram, arrival_s):
                self.localisation.receive(output, arrival_s)

    def tick(self, truth: TruthSample) -> None:
        """One tick at the truth's time: send, deliver, poll, localise, acknowledge, record."""
        now_s = truth.time_s
        for datagram in self.modules.step(truth):
            self.link.send(datagram, now_s)
        self.deliver(now_s)
        for output in self.listener.poll(now_s):
            self.localisation.receive(output, now_s)
        for ack in self.localisation.step(now_s):
            self.listener.on_ack(ack, now_s)
        if self.recording is not None:
            self.recording.add_truth(truth)


@dataclass
class _TickErrors:
    """The estimate's errors at each tick that had one, in arrays sized for every tick."""

    times_s: FloatArray
    position_errors_m: FloatArray
    speed_errors_mps: FloatArray
    odometer_alive: npt.NDArray[np.bool_]
    lost: npt.NDArray[np.bool_]
    count: int = 0

    @classmethod
    def sized(cls, ticks: int) -> _TickErrors:
        return cls(
            times_s=np.zeros(ticks),
            position_errors_m=np.zeros(ticks),
            speed_errors_mps=np.zeros(ticks),
            odometer_alive=np.ones(ticks, dtype=bool),
            lost=np.zeros(ticks, dtype=bool),
        )

    def add(self, truth: TruthSample, estimate: LocalisationEstimate) -> None:
        count = self.count
        self.times_s[count] = truth.time_s
        self.position_errors_m[count] = estimate.position_m - truth.position_m
        self.speed_errors_mps[count] = estimate.speed_mps - truth.speed_mps
        self.odometer_alive[count] = bool(estimate.odometer_alive)
        self.lost[count] = estimate.health is Health.LOST
        self.count = count + 1
