"""The interface-modules of seed 002 §3.1, emulated from the plant's truth.

The real vehicle's interface-modules read the IMU, the radar/odometer and the GPS receiver and
send each sample to the listener as an INPUT_PROTOCOL datagram (CONTRACT.md §3). Here the
samples are made from the plant's truth (:class:`TruthSample`) with the sensors' errors:

- IMU, 100 Hz: specific force in the body frame (x forward, y right, z down): the longitudinal
  acceleration plus g sin θ along x (θ the pitch of the gradient), the curve's centripetal
  acceleration −v²κ along y (κ > 0 turning left), −g cos θ along z; gyro rates (0, 0, −vκ).
  Each axis has a constant bias drawn at start and white noise.
- odometer/radar, 20 Hz: the wheel's circumferential speed when the truth has it (the bogie
  model: slip and slide show), else the vehicle's speed; white noise, and σ sent with it.
- GPS, 1 Hz: the line's geodetic polyline at the true chainage, with horizontal and vertical
  white noise in metres.
- STROBE once a second (the sender's time), GROUND_TRUTH at start, STOP at the end.

All packets share one sequence counter. Sensor faults are windows of time: outages (no packet),
and a failed odometer reading zero. The stream is a pure function of the truth and the seed of
the numpy ``Generator`` passed in. Link faults (loss, reordering, …) are not here: see
:mod:`onboard.sfa.link`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from onboard.plant.interfaces import BogieTruth
from onboard.plant.point_mass import GRAVITY_MPS2
from protocol.udp import SEQ_MODULO, InputPacket, SensorType, encode_input
from trackdb import TrackMap

__all__ = [
    "EARTH_RADIUS_M",
    "InterfaceModules",
    "SensorFaults",
    "SensorNoise",
    "TimeWindow",
    "TruthSample",
    "truth_from_bogie",
]

EARTH_RADIUS_M = 6_371_000.0
NORMAL_BLOCK = 4096
"""Standard normal draws taken from the generator at a time."""


@dataclass(frozen=True, slots=True)
class TruthSample:
    """The vehicle's truth at one instant, SI units.

    ``position_m`` is unwrapped (on a ring it keeps counting past the origin);
    ``wheel_speed_mps`` is the wheel's circumferential speed when the plant models it.
    """

    time_s: float
    position_m: float
    speed_mps: float
    acceleration_mps2: float
    wheel_speed_mps: float | None = None


def truth_from_bogie(truth: BogieTruth) -> TruthSample:
    """The bogie model's truth, with the front wheel's circumferential speed for the odometer."""
    return TruthSample(
        time_s=truth.time_s,
        position_m=truth.position_m,
        speed_mps=truth.speed_mps,
        acceleration_mps2=truth.acceleration_mps2,
        wheel_speed_mps=truth.wheel_speed_front_radps * truth.wheel_radius_m,
    )


@dataclass(frozen=True, slots=True)
class TimeWindow:
    """From ``start_s`` (included) to ``end_s`` (excluded) [s]."""

    start_s: float
    end_s: float

    def __contains__(self, time_s: object) -> bool:
        return isinstance(time_s, float | int) and self.start_s <= time_s < self.end_s


@dataclass(frozen=True, kw_only=True)
class SensorNoise:
    """σ of each sensor's errors (SI units)."""

    accelerometer_noise_mps2: float = 0.02
    accelerometer_bias_sigma_mps2: float = 0.05
    gyro_noise_radps: float = 0.001
    gyro_bias_sigma_radps: float = 0.0005
    odometer_sigma_mps: float = 0.05
    gps_horizontal_sigma_m: float = 1.5
    gps_vertical_sigma_m: float = 3.0


@dataclass(frozen=True, kw_only=True)
class SensorFaults:
    """Sensor faults as windows of the sender's time."""

    imu_outages: tuple[TimeWindow, ...] = ()
    odometer_outages: tuple[TimeWindow, ...] = ()
    odometer_stuck_at_zero: tuple[TimeWindow, ...] = ()
    gps_outages: tuple[TimeWindow, ...] = ()


def _inside(windows: tuple[TimeWindow, ...], time_s: float) -> bool:
    return any(window.start_s <= time_s < window.end_s for window in windows)


class InterfaceModules:
    """Truth in, INPUT_PROTOCOL datagrams out, one IMU tick at a time.

    Parameters
    ----------
    track_map : TrackMap
        The line: gradient and curvature for the IMU, geodesy for the GPS.
    rng : numpy.random.Generator
        The only source of randomness (biases and noise).
    noise, faults :
        The sensors' errors and fault windows.
    imu_rate_hz, odometer_rate_hz, gps_rate_hz : int
        Sample rates; the odometer's and the GPS's must divide the IMU's.
    """

    def __init__(
        self,
        track_map: TrackMap,
        *,
        rng: np.random.Generator,
        noise: SensorNoise | None = None,
        faults: SensorFaults | None = None,
        imu_rate_hz: int = 100,
        odometer_rate_hz: int = 20,
        gps_rate_hz: int = 1,
    ) -> None:
        if imu_rate_hz % odometer_rate_hz or imu_rate_hz % gps_rate_hz:
            raise ValueError("the odometer and GPS rates must divide the IMU rate")
        self.track_map = track_map
        self.rng = rng
        self.noise = noise or SensorNoise()
        self.faults = faults or SensorFaults()
        self.imu_rate_hz = imu_rate_hz
        self._odometer_every = imu_rate_hz // odometer_rate_hz
        self._gps_every = imu_rate_hz // gps_rate_hz
        n = self.noise
        self.accelerometer_bias_mps2 = tuple(
            rng.normal(0.0, n.accelerometer_bias_sigma_mps2, size=3).tolist()
        )
        self.gyro_bias_radps = tuple(rng.normal(0.0, n.gyro_bias_sigma_radps, size=3).tolist())
        self._normals: list[float] = []
        self._next_normal = 0
        self._sequence = 0
        self._tick = 0
        self._start_s = 0.0
        self._has_geodesy = bool(track_map.line.geodetic)

    def _packet(self, sensor_type: SensorType, doubles: tuple[float, ...]) -> bytes:
        datagram = encode_input(InputPacket(sensor_type, self._sequence, doubles))
        self._sequence = (self._sequence + 1) % SEQ_MODULO
        return datagram

    def start(self, truth: TruthSample) -> list[bytes]:
        """GROUND_TRUTH: the initial velocity (body x forward) and chainage [km]."""
        self._start_s = truth.time_s
        self._tick = 0
        chainage_km = self.track_map.normalise(truth.position_m) / 1000.0
        return [self._packet(SensorType.GROUND_TRUTH, (truth.speed_mps, 0.0, 0.0, chainage_km))]

    def stop(self) -> list[bytes]:
        return [self._packet(SensorType.STOP, ())]

    def step(self, truth: TruthSample) -> list[bytes]:
        """The datagrams of the IMU tick at ``truth.time_s``: STROBE on whole seconds, IMU,
        odometer and GPS when due. Call once per IMU period, from :meth:`start`'s instant."""
        tick = self._tick
        self._tick += 1
        time_s = self._start_s + tick / self.imu_rate_hz
        faults = self.faults
        datagrams: list[bytes] = []
        if tick % self.imu_rate_hz == 0:
            datagrams.append(self._packet(SensorType.STROBE, (time_s,)))
        if not _inside(faults.imu_outages, time_s):
            datagrams.append(self._packet(SensorType.IMU, self.imu_sample(truth)))
        if tick % self._odometer_every == 0 and not _inside(faults.odometer_outages, time_s):
            datagrams.append(self._packet(SensorType.ODOMETER, self.odometer_sample(truth)))
        if (
            tick % self._gps_every == 0
            and self._has_geodesy
            and not _inside(faults.gps_outages, time_s)
        ):
            datagrams.append(self._packet(SensorType.GPS, self.gps_sample(truth)))
        return datagrams

    def _white(self, count: int) -> list[float]:
        """The next ``count`` standard normal draws, taken from the generator in blocks (one
        draw at a time from numpy costs more than the rest of an IMU sample)."""
        start = self._next_normal
        if start + count > len(self._normals):
            self._normals = self._normals[start:] + self.rng.standard_normal(NORMAL_BLOCK).tolist()
            start = 0
        self._next_normal = start + count
        return self._normals[start : start + count]

    def imu_sample(self, truth: TruthSample) -> tuple[float, ...]:
        """(acc x, y, z [m/s²], gyro x, y, z [rad/s]) in the body frame."""
        track_map, n = self.track_map, self.noise
        pitch = math.atan(track_map.gradient_permille(truth.position_m) / 1000.0)
        curvature = track_map.curvature_per_m(truth.position_m)
        speed = truth.speed_mps
        white = self._white(6)
        acc_bias, gyro_bias = self.accelerometer_bias_mps2, self.gyro_bias_radps
        acc_noise, gyro_noise = n.accelerometer_noise_mps2, n.gyro_noise_radps
        return (
            truth.acceleration_mps2
            + GRAVITY_MPS2 * math.sin(pitch)
            + acc_bias[0]
            + acc_noise * white[0],
            -speed * speed * curvature + acc_bias[1] + acc_noise * white[1],
            -GRAVITY_MPS2 * math.cos(pitch) + acc_bias[2] + acc_noise * white[2],
            gyro_bias[0] + gyro_noise * white[3],
            gyro_bias[1] + gyro_noise * white[4],
            -speed * curvature + gyro_bias[2] + gyro_noise * white[5],
        )

    def odometer_sample(self, truth: TruthSample) -> tuple[float, float]:
        """(speed [m/s], σ [m/s])."""
        sigma = self.noise.odometer_sigma_mps
        speed = truth.speed_mps if truth.wheel_speed_mps is None else truth.wheel_speed_mps
        measured = speed + sigma * self._white(1)[0]
        time_s = self._start_s + (self._tick - 1) / self.imu_rate_hz
        if _inside(self.faults.odometer_stuck_at_zero, time_s):
            measured = 0.0
        return measured, sigma

    def gps_sample(self, truth: TruthSample) -> tuple[float, float, float]:
        """(latitude [deg], longitude [deg], altitude [m]) with noise."""
        latitude, longitude, altitude = self.track_map.geodetic_at(truth.position_m)
        n = self.noise
        north, east, up = self._white(3)
        degrees_per_m = 180.0 / (math.pi * EARTH_RADIUS_M)
        return (
            latitude + north * n.gps_horizontal_sigma_m * degrees_per_m,
            longitude
            + east * n.gps_horizontal_sigma_m * degrees_per_m / math.cos(math.radians(latitude)),
            altitude + up * n.gps_vertical_sigma_m,
        )
