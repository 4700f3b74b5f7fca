"""Sensor-fusion positioning after seed 002: SFA (the sensor-fusion algorithm), its listener
and the OBCU's localisation input.

- :mod:`~onboard.sfa.filter`: the Kalman filter along the track (IMU input; odometer, GPS and
  balise-group measurements).
- :mod:`~onboard.sfa.reorder` and :mod:`~onboard.sfa.listener`: INPUT_PROTOCOL validated,
  reordered and fused; OUTPUT_PROTOCOL out; ACKs tracked. :mod:`~onboard.sfa.time_base`: the
  sensor packets' epochs from the STROBEs.
- :mod:`~onboard.sfa.localisation`: the OBCU (on-board control unit) side.
- :mod:`~onboard.sfa.sockets`: the listener and the OBCU over real UDP sockets
  (``ato sfa listen``).
- :mod:`~onboard.sfa.link`: fault injection on the sensors' link;
  :mod:`~onboard.sfa.chain`: the whole chain as the onboard node steps it.

The emulated drive, the chain in lockstep against the truth and the offline configuration
(record, replay) drive and score the chain from outside: ``deploy.bench.sfa_drive``,
``deploy.bench.sfa_lockstep``, ``deploy.bench.sfa_recording``.

Wire formats: CONTRACT.md §3, codecs in :mod:`protocol.udp`. Design notes: docs/sfa.md.
"""

from onboard.sfa._exceptions import AddressError, NotInitialisedError, SfaError
from onboard.sfa.filter import FilterConfig, TrackKalmanFilter
from onboard.sfa.link import FaultyLink, LinkFaults
from onboard.sfa.listener import (
    ALL_SENSORS,
    Health,
    ListenerConfig,
    ListenerCore,
    ListenerCounters,
    SfaStatus,
)
from onboard.sfa.localisation import Localisation, LocalisationEstimate
from onboard.sfa.reorder import ReorderBuffer
from onboard.sfa.time_base import SensorTimeBase

__all__ = [
    "ALL_SENSORS",
    "AddressError",
    "FaultyLink",
    "FilterConfig",
    "Health",
    "LinkFaults",
    "ListenerConfig",
    "ListenerCore",
    "ListenerCounters",
    "Localisation",
    "LocalisationEstimate",
    "NotInitialisedError",
    "ReorderBuffer",
    "SensorTimeBase",
    "SfaError",
    "SfaStatus",
    "TrackKalmanFilter",
]
