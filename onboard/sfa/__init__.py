"""Sensor-fusion positioning after seed 002: SFA (the sensor-fusion algorithm), its listener
and the OBCU's localisation input.

- :mod:`~onboard.sfa.filter`: the Kalman filter along the track (IMU input; odometer, GPS and
  balise-group measurements).
- :mod:`~onboard.sfa.reorder` and :mod:`~onboard.sfa.listener`: INPUT_PROTOCOL validated,
  reordered and fused; OUTPUT_PROTOCOL out; ACKs tracked.
- :mod:`~onboard.sfa.localisation`: the OBCU (on-board control unit) side.
- :mod:`~onboard.sfa.runner`: the same over real UDP sockets (``ato sfa listen``).
- :mod:`~onboard.sfa.link`, :mod:`~onboard.sfa.drive`, :mod:`~onboard.sfa.lockstep`: fault
  injection, a driven plant and the whole chain in lockstep.
- :mod:`~onboard.sfa.recording`: the offline configuration (record, replay).

Wire formats: CONTRACT.md §3, codecs in :mod:`protocol.udp`. Design notes: docs/sfa.md.
"""

from onboard.sfa._exceptions import AddressError, NotInitialisedError, RecordingError, SfaError
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
from onboard.sfa.lockstep import DriveResult, DriveSettings, ErrorStats, run_lockstep
from onboard.sfa.recording import Recording, ReplayResult, replay
from onboard.sfa.reorder import ReorderBuffer

__all__ = [
    "ALL_SENSORS",
    "AddressError",
    "DriveResult",
    "DriveSettings",
    "ErrorStats",
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
    "Recording",
    "RecordingError",
    "ReorderBuffer",
    "ReplayResult",
    "SfaError",
    "SfaStatus",
    "TrackKalmanFilter",
    "replay",
    "run_lockstep",
]
