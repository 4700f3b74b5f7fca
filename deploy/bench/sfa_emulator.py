"""The interface-modules emulator on a UDP socket (``ato sfa emulate``): an emulated drive's
INPUT datagrams sent to a listener, paced against a clock.

The same emulator (:class:`~onboard.plant.sensors.InterfaceModules`) and link
(:class:`~onboard.sfa.link.FaultyLink`) as inside the onboard node, on the truth of a
:class:`~deploy.bench.sfa_drive.SpeedProfileDrive`: a bench for a listener running on its own
(``ato sfa listen``, seed 002 §4.1.1).
"""

from __future__ import annotations

import itertools
import socket
import time
from collections.abc import Callable

import numpy as np

from deploy.bench.sfa_drive import DriveSettings, SpeedProfileDrive
from onboard.plant.sensors import InterfaceModules
from onboard.sfa.link import FaultyLink
from onboard.sfa.sockets import Address, Clock
from trackdb import TrackMap

__all__ = ["send_drive"]


def send_drive(
    settings: DriveSettings,
    track_map: TrackMap,
    destination: Address,
    *,
    speed_factor: float = 1.0,
    clock: Clock = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Emulate a drive and send its datagrams over UDP, paced at ``speed_factor`` × real time
    (``inf``: as fast as possible); link faults are applied before sending. Returns the number
    of datagrams sent."""
    rng = np.random.default_rng(settings.seed)
    drive = SpeedProfileDrive(track_map, start_m=settings.start_m, cruise_kmh=settings.cruise_kmh)
    modules = InterfaceModules(
        track_map, rng=rng, noise=settings.noise, faults=settings.sensor_faults
    )
    link = FaultyLink(settings.link_faults, rng)
    sent = 0
    started_s = clock()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        truths = drive.run(settings.duration_s)
        first = next(truths)
        for datagram in modules.start(first):
            link.send(datagram, first.time_s)
        for truth in itertools.chain([first], truths):
            for datagram in modules.step(truth):
                link.send(datagram, truth.time_s)
            due = link.deliver(truth.time_s)
            if speed_factor != float("inf"):
                ahead_s = truth.time_s / speed_factor - (clock() - started_s)
                if ahead_s > 0:
                    sleep(ahead_s)
            for datagram, _ in due:
                sock.sendto(datagram, destination)
                sent += 1
        for datagram in modules.stop():
            link.send(datagram, drive.time_s)
        for datagram, _ in link.drain():
            sock.sendto(datagram, destination)
            sent += 1
    return sent
