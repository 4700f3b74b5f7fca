"""The offline configuration of seed 002 §4.1.2: recordings and their replay.

A recording holds the INPUT datagrams exactly as the listener received them, with their arrival
times, and the truth (time, unwrapped position, speed) when it is known. It is one ``.npz`` file
(numpy arrays only, never pickle):

- ``datagrams`` uint8, every datagram's bytes end to end; ``offsets`` int64, n + 1 bounds;
- ``arrival_s`` float64, n arrival times;
- ``truth_time_s``, ``truth_position_m``, ``truth_speed_mps`` float64 (maybe empty);
- ``line_id`` a one-element unicode array.

:func:`replay` feeds a recording through a fresh listener, as fast as the CPU allows, with the
sensors and noise covariances chosen, and compares every OUTPUT with the truth at its epoch.
Since epochs come from the STROBE timestamps, the replay's estimates do not depend on its pace.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from deploy._exceptions import DeployError
from onboard.plant.sensors import TruthSample
from onboard.sfa.listener import ListenerConfig, ListenerCore, SfaStatus
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap, load_seed_line

__all__ = ["Recording", "RecordingError", "ReplayResult", "replay"]

FloatArray = npt.NDArray[np.float64]


class RecordingError(DeployError, ValueError):
    """An offline recording is unreadable or inconsistent."""


@dataclass
class Recording:
    """INPUT datagrams with arrival times, and the truth."""

    line_id: str
    datagrams: list[bytes] = field(default_factory=list)
    arrival_s: list[float] = field(default_factory=list)
    truth_time_s: list[float] = field(default_factory=list)
    truth_position_m: list[float] = field(default_factory=list)
    truth_speed_mps: list[float] = field(default_factory=list)

    @classmethod
    def empty(cls, line_id: str) -> Recording:
        return cls(line_id=line_id)

    def add_datagram(self, datagram: bytes, arrival_s: float) -> None:
        self.datagrams.append(datagram)
        self.arrival_s.append(arrival_s)

    def add_truth(self, truth: TruthSample) -> None:
        self.truth_time_s.append(truth.time_s)
        self.truth_position_m.append(truth.position_m)
        self.truth_speed_mps.append(truth.speed_mps)

    def save(self, path: Path) -> None:
        """Write the ``.npz`` file (the suffix is added by numpy if missing)."""
        lengths = np.array([len(d) for d in self.datagrams], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
        payload = np.frombuffer(b"".join(self.datagrams), dtype=np.uint8)
        try:
            np.savez_compressed(
                path,
                datagrams=payload,
                offsets=offsets,
                arrival_s=np.asarray(self.arrival_s, dtype=np.float64),
                truth_time_s=np.asarray(self.truth_time_s, dtype=np.float64),
                truth_position_m=np.asarray(self.truth_position_m, dtype=np.float64),
                truth_speed_mps=np.asarray(self.truth_speed_mps, dtype=np.float64),
                line_id=np.array([self.line_id]),
            )
        except OSError as exc:
            raise RecordingError(f"cannot write {path}: {exc}") from exc

    @classmethod
    def load(cls, path: Path) -> Recording:
        """Read a recording written by :meth:`save`.

        Raises
        ------
        RecordingError
            If the file is missing, not an ``.npz`` or inconsistent.
        """
        try:
            with np.load(path, allow_pickle=False) as data:
                payload = bytes(data["datagrams"].astype(np.uint8))
                offsets = data["offsets"].astype(np.int64)
                arrival = data["arrival_s"].astype(np.float64)
                truth = [data[k].astype(np.float64) for k in _TRUTH_KEYS]
                line_id = str(data["line_id"][0])
        except (OSError, KeyError, ValueError, IndexError, zipfile.BadZipFile) as exc:
            raise RecordingError(f"cannot read recording {path}: {exc}") from exc
        if offsets.size != arrival.size + 1 or (offsets.size and offsets[-1] != len(payload)):
            raise RecordingError(f"recording {path}: offsets do not match the datagrams")
        if not truth[0].size == truth[1].size == truth[2].size:
            raise RecordingError(f"recording {path}: truth arrays differ in length")
        return cls(
            line_id=line_id,
            datagrams=[payload[offsets[i] : offsets[i + 1]] for i in range(arrival.size)],
            arrival_s=arrival.tolist(),
            truth_time_s=truth[0].tolist(),
            truth_position_m=truth[1].tolist(),
            truth_speed_mps=truth[2].tolist(),
        )


_TRUTH_KEYS = ("truth_time_s", "truth_position_m", "truth_speed_mps")


@dataclass(frozen=True)
class ReplayResult:
    """Estimates at each OUTPUT epoch and their errors against the truth."""

    epochs_s: FloatArray
    position_errors_m: FloatArray
    speed_errors_mps: FloatArray
    sigma_m: FloatArray
    listener: ListenerCore

    @property
    def position_rms_m(self) -> float:
        return float(np.sqrt(np.mean(self.position_errors_m**2)))

    @property
    def position_max_m(self) -> float:
        return float(np.max(np.abs(self.position_errors_m)))

    @property
    def speed_rms_kmh(self) -> float:
        return float(np.sqrt(np.mean(self.speed_errors_mps**2)) / MPS_PER_KMH)


def replay(
    recording: Recording,
    config: ListenerConfig | None = None,
    track_map: TrackMap | None = None,
) -> ReplayResult:
    """Feed a recording through a fresh listener and compare its outputs with the truth.

    Raises
    ------
    RecordingError
        If the recording has no truth or produced no output.
    """
    track_map = track_map or TrackMap(load_seed_line(recording.line_id))
    published: list[SfaStatus] = []
    listener = ListenerCore(track_map, config, on_output=published.append)
    for datagram, arrival_s in zip(recording.datagrams, recording.arrival_s, strict=True):
        listener.feed(datagram, arrival_s)
    epochs = [status.epoch_s for status in published]
    positions = [status.chainage_m for status in published]
    speeds = [status.speed_mps for status in published]
    sigmas = [status.sigma_m for status in published]
    if not recording.truth_time_s or not epochs:
        raise RecordingError("the recording has no truth, or the listener produced no output")
    truth_time = np.asarray(recording.truth_time_s)
    epoch_array = np.asarray(epochs)
    true_position = np.interp(epoch_array, truth_time, np.asarray(recording.truth_position_m))
    true_speed = np.interp(epoch_array, truth_time, np.asarray(recording.truth_speed_mps))
    return ReplayResult(
        epochs_s=epoch_array,
        position_errors_m=np.asarray(positions) - true_position,
        speed_errors_mps=np.asarray(speeds) - true_speed,
        sigma_m=np.asarray(sigmas),
        listener=listener,
    )
