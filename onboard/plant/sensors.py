"""The interface-modules of seed 002 §3.1, emulated from the plant's truth.

The real vehicle's interface-modules read the IMU, the radar/odometer and the GPS receiver and
send each sample to the listener as an INPUT_PROTOCOL datagram (CONTRACT.md §3). Here the
samples are made from the plant's truth (:class:`TruthSample`) with the sensors' errors
(:class:`SensorNoise`; sources and values in docs/sensors.md):

- IMU, 100 Hz: specific force in the body frame (x forward, y right, z down): the longitudinal
  acceleration plus g sin θ along x (θ the pitch of the gradient), the curve's centripetal
  acceleration −v²κ along y (κ > 0 turning left), −g cos θ along z; gyro rates (0, 0, −vκ).
  Each axis has a scale-factor error and a bias drawn at start, a bias random walk (the bias
  instability, stepped once a second) and white noise.
- odometer, 20 Hz: wheel-based. The wheel's circumferential speed when the truth has it (the
  bogie model: slip and slide show), else the vehicle's speed, read through the calibrated
  wheel diameter (the same ``diameter_error`` as :class:`~onboard.plant.wheel_sensors.
  WheelSensors`), counted in pulses (the speed is the count over the sample interval, so it is
  quantised), plus white noise; the σ sent covers the noise and the quantisation.
- GPS, 1 Hz: the line's geodetic polyline at the chainage the train had ``gps_latency_s`` ago,
  with a first-order Gauss–Markov error per axis (north, east, up), white noise, and rare
  multipath jumps (a horizontal offset of some metres for some seconds).
- STROBE once a second (the sender's time), GROUND_TRUTH at start, STOP at the end.

All packets share one sequence counter. Sensor faults are windows of time: outages (no packet),
and a failed odometer reading zero. The stream is a pure function of the truth and the seed of
the numpy ``Generator`` passed in. Link faults (loss, reordering, …) are not here: see
:mod:`onboard.sfa.link`.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from onboard.plant.interfaces import BogieTruth
from onboard.plant.readings import WheelReading
from onboard.plant.wheel_sensors import (
    DIAMETER_ERROR_SIGMA,
    PulseCounter,
    WheelSensors,
    draw_diameter_error,
)
from protocol.udp import SEQ_MODULO, InputPacket, SensorType, encode_input
from protocol.units import GRAVITY_MPS2
from trackdb import TrackMap

__all__ = [
    "EARTH_RADIUS_M",
    "ODOMETER_COUNT_M",
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
ODOMETER_COUNT_M = math.pi * 0.92 / 800.0
"""Travel per odometer count [m]: a 200-tooth pulse wheel on a 0.92 m wheel, both edges of two
channels in quadrature counted (800 counts a revolution), 3.6 mm."""


@dataclass(frozen=True, slots=True)
class TruthSample:
    """The vehicle's truth at one instant, SI units.

    ``position_m`` is unwrapped (on a ring it keeps counting past the origin);
    ``wheel_speed_mps`` and ``wheel_speed_rear_mps`` are the front and rear wheels'
    circumferential speeds when the plant models them (the bogie model).
    """

    time_s: float
    position_m: float
    speed_mps: float
    acceleration_mps2: float
    wheel_speed_mps: float | None = None
    wheel_speed_rear_mps: float | None = None


def truth_from_bogie(truth: BogieTruth) -> TruthSample:
    """The bogie model's truth, with the wheels' circumferential speeds (the odometer reads the
    front one)."""
    return TruthSample(
        time_s=truth.time_s,
        position_m=truth.position_m,
        speed_mps=truth.speed_mps,
        acceleration_mps2=truth.acceleration_mps2,
        wheel_speed_mps=truth.wheel_speed_front_radps * truth.wheel_radius_m,
        wheel_speed_rear_mps=truth.wheel_speed_rear_radps * truth.wheel_radius_m,
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
    """The sensors' error model (SI units; scale factors dimensionless). σ values are of zero-mean
    normal draws; docs/sensors.md gives each value's source.

    Attributes
    ----------
    accelerometer_noise_mps2, gyro_noise_radps : float
        σ of the white noise of each IMU sample, per axis.
    accelerometer_bias_sigma_mps2, gyro_bias_sigma_radps : float
        σ of the turn-on bias, drawn once per axis.
    accelerometer_bias_walk_mps2_per_sqrt_s, gyro_bias_walk_radps_per_sqrt_s : float
        Intensity of the bias random walk (bias instability) per axis [unit/√s].
    accelerometer_scale_sigma, gyro_scale_sigma : float
        σ of the scale-factor error, drawn once per axis.
    odometer_sigma_mps : float
        σ of the odometer's white noise [m/s].
    odometer_scale_sigma : float
        σ of the wheel-diameter error when none is given (see ``draw_diameter_error``).
    odometer_count_m : float
        Travel per pulse count [m]; 0 turns quantisation off.
    gps_horizontal_sigma_m, gps_vertical_sigma_m : float
        σ of the GPS fix's white error per horizontal axis and vertically [m].
    gps_correlated_horizontal_sigma_m, gps_correlated_vertical_sigma_m : float
        Stationary σ of the first-order Gauss–Markov error per axis [m].
    gps_correlation_time_s : float
        Correlation time of the Gauss–Markov error [s].
    gps_latency_s : float
        Age of the position a fix reports when it is sent [s] (rounded to the IMU period).
    gps_multipath_rate_per_s : float
        Mean rate of multipath events [1/s] (a Poisson process sampled at each fix).
    gps_multipath_offset_m, gps_multipath_duration_s : tuple of float
        (low, high) of the uniform horizontal offset [m] (in a uniform direction) and duration
        [s] of an event.
    """

    accelerometer_noise_mps2: float = 0.02
    accelerometer_bias_sigma_mps2: float = 0.05
    accelerometer_bias_walk_mps2_per_sqrt_s: float = 1e-4
    accelerometer_scale_sigma: float = 1e-3
    gyro_noise_radps: float = 0.001
    gyro_bias_sigma_radps: float = 0.0005
    gyro_bias_walk_radps_per_sqrt_s: float = 2e-6
    gyro_scale_sigma: float = 1e-3
    odometer_sigma_mps: float = 0.05
    odometer_scale_sigma: float = DIAMETER_ERROR_SIGMA
    odometer_count_m: float = ODOMETER_COUNT_M
    gps_horizontal_sigma_m: float = 0.15
    gps_vertical_sigma_m: float = 0.3
    gps_correlated_horizontal_sigma_m: float = 0.15
    gps_correlated_vertical_sigma_m: float = 0.3
    gps_correlation_time_s: float = 60.0
    gps_latency_s: float = 0.1
    gps_multipath_rate_per_s: float = 1.0 / 600.0
    gps_multipath_offset_m: tuple[float, float] = (3.0, 10.0)
    gps_multipath_duration_s: tuple[float, float] = (2.0, 8.0)

    @classmethod
    def noiseless(cls) -> SensorNoise:
        """Every error zero: the truth, sampled (the odometer still counts nothing finer than
        nothing: quantisation off)."""
        return cls(
            accelerometer_noise_mps2=0.0,
            accelerometer_bias_sigma_mps2=0.0,
            accelerometer_bias_walk_mps2_per_sqrt_s=0.0,
            accelerometer_scale_sigma=0.0,
            gyro_noise_radps=0.0,
            gyro_bias_sigma_radps=0.0,
            gyro_bias_walk_radps_per_sqrt_s=0.0,
            gyro_scale_sigma=0.0,
            odometer_sigma_mps=0.0,
            odometer_scale_sigma=0.0,
            odometer_count_m=0.0,
            gps_horizontal_sigma_m=0.0,
            gps_vertical_sigma_m=0.0,
            gps_correlated_horizontal_sigma_m=0.0,
            gps_correlated_vertical_sigma_m=0.0,
            gps_latency_s=0.0,
            gps_multipath_rate_per_s=0.0,
        )


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
        The only source of randomness (biases, scale factors, noise, multipath).
    noise, faults :
        The sensors' error model and fault windows.
    imu_rate_hz, odometer_rate_hz, gps_rate_hz : int
        Sample rates; the odometer's and the GPS's must divide the IMU's.
    diameter_error : float, optional
        The odometer wheel's calibrated over real diameter minus 1 (dimensionless): pass the
        value the axle sensors use, so that both read the same wheel alike. By default drawn
        from ``rng`` with σ ``noise.odometer_scale_sigma``.
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
        diameter_error: float | None = None,
    ) -> None:
        if imu_rate_hz % odometer_rate_hz or imu_rate_hz % gps_rate_hz:
            raise ValueError("the odometer and GPS rates must divide the IMU rate")
        self.track_map = track_map
        self.rng = rng
        self.noise = n = noise or SensorNoise()
        self.faults = faults or SensorFaults()
        self.imu_rate_hz = imu_rate_hz
        self.odometer_period_s = 1.0 / odometer_rate_hz
        self._odometer_every = imu_rate_hz // odometer_rate_hz
        self._gps_every = imu_rate_hz // gps_rate_hz
        self.accelerometer_bias_mps2 = tuple(
            rng.normal(0.0, n.accelerometer_bias_sigma_mps2, size=3).tolist()
        )
        """Each accelerometer axis's bias now [m/s²]: the turn-on bias plus its random walk."""
        self.gyro_bias_radps = tuple(rng.normal(0.0, n.gyro_bias_sigma_radps, size=3).tolist())
        """Each gyro axis's bias now [rad/s]."""
        self.accelerometer_scale = tuple(
            (1.0 + rng.normal(0.0, n.accelerometer_scale_sigma, size=3)).tolist()
        )
        """Each accelerometer axis's scale factor (1 + error)."""
        self.gyro_scale = tuple((1.0 + rng.normal(0.0, n.gyro_scale_sigma, size=3)).tolist())
        if diameter_error is None:
            diameter_error = draw_diameter_error(rng, n.odometer_scale_sigma)
        self.diameter_error = diameter_error
        self.gps_error_m = (0.0, 0.0, 0.0)
        """The last fix's error (north, east, up) [m], multipath included."""
        self.multipath_events = 0
        self._normals: list[float] = []
        self._next_normal = 0
        self._sequence = 0
        self._tick = 0
        self._start_s = 0.0
        self._has_geodesy = bool(track_map.line.geodetic)
        self._odometer_wheel = WheelSensors(rng=rng, diameter_error=diameter_error)
        self._odometer_reading: WheelReading | None = None
        self._odometer_counter = PulseCounter(n.odometer_count_m)
        latency_ticks = max(round(n.gps_latency_s * imu_rate_hz), 0)
        self._positions_m: deque[float] = deque(maxlen=latency_ticks + 1)
        self._gps = _GpsErrors(n)

    def _packet(self, sensor_type: SensorType, doubles: tuple[float, ...]) -> bytes:
        datagram = encode_input(InputPacket(sensor_type, self._sequence, doubles))
        self._sequence = (self._sequence + 1) % SEQ_MODULO
        return datagram

    def start(self, truth: TruthSample) -> list[bytes]:
        """GROUND_TRUTH: the initial velocity (body x forward) and chainage [km]."""
        self._start_s = truth.time_s
        self._tick = 0
        self._odometer_wheel = WheelSensors(rng=self.rng, diameter_error=self.diameter_error)
        self._odometer_reading = None
        self._odometer_counter = PulseCounter(self.noise.odometer_count_m)
        self._positions_m.clear()
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
        self._read_odometer_wheel(truth)
        self._positions_m.append(truth.position_m)
        if tick % self.imu_rate_hz == 0:
            if tick:
                self._walk_biases(1.0)
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

    def _walk_biases(self, dt_s: float) -> None:
        """One step of the IMU biases' random walks over ``dt_s`` [s]."""
        n, root_dt = self.noise, math.sqrt(dt_s)
        white = self._white(6)
        acc_step = n.accelerometer_bias_walk_mps2_per_sqrt_s * root_dt
        gyro_step = n.gyro_bias_walk_radps_per_sqrt_s * root_dt
        self.accelerometer_bias_mps2 = tuple(
            bias + acc_step * w
            for bias, w in zip(self.accelerometer_bias_mps2, white[:3], strict=True)
        )
        self.gyro_bias_radps = tuple(
            bias + gyro_step * w for bias, w in zip(self.gyro_bias_radps, white[3:], strict=True)
        )

    def imu_sample(self, truth: TruthSample) -> tuple[float, ...]:
        """(acc x, y, z [m/s²], gyro x, y, z [rad/s]) in the body frame."""
        track_map, n = self.track_map, self.noise
        pitch = math.atan(track_map.gradient_permille(truth.position_m) / 1000.0)
        curvature = track_map.curvature_per_m(truth.position_m)
        speed = truth.speed_mps
        white = self._white(6)
        acc_bias, gyro_bias = self.accelerometer_bias_mps2, self.gyro_bias_radps
        acc_scale, gyro_scale = self.accelerometer_scale, self.gyro_scale
        acc_noise, gyro_noise = n.accelerometer_noise_mps2, n.gyro_noise_radps
        return (
            acc_scale[0] * (truth.acceleration_mps2 + GRAVITY_MPS2 * math.sin(pitch))
            + acc_bias[0]
            + acc_noise * white[0],
            acc_scale[1] * (-speed * speed * curvature) + acc_bias[1] + acc_noise * white[1],
            acc_scale[2] * (-GRAVITY_MPS2 * math.cos(pitch)) + acc_bias[2] + acc_noise * white[2],
            gyro_bias[0] + gyro_noise * white[3],
            gyro_bias[1] + gyro_noise * white[4],
            gyro_scale[2] * (-speed * curvature) + gyro_bias[2] + gyro_noise * white[5],
        )

    def _read_odometer_wheel(self, truth: TruthSample) -> WheelReading:
        """The odometer wheel's reading at ``truth.time_s`` (read once per instant)."""
        reading = self._odometer_reading
        if reading is None or truth.time_s > reading.time_s:
            reading = self._odometer_reading = self._odometer_wheel.step(truth)
        return reading

    def odometer_sample(self, truth: TruthSample) -> tuple[float, float]:
        """(speed [m/s], σ [m/s]): the pulses counted since the last sample over the time
        between them, plus white noise; σ covers the noise and the quantisation."""
        n = self.noise
        wheel = self._read_odometer_wheel(truth)
        speed = self._odometer_counter.speed(
            wheel.travel_front_m, wheel.speed_front_mps, wheel.time_s, self.odometer_period_s
        )
        measured = speed + n.odometer_sigma_mps * self._white(1)[0]
        time_s = self._start_s + (self._tick - 1) / self.imu_rate_hz
        if _inside(self.faults.odometer_stuck_at_zero, time_s):
            measured = 0.0
        resolution_mps = n.odometer_count_m / self.odometer_period_s
        # The difference of two uniform rounding errors of one count: variance LSB² / 6.
        sigma = math.sqrt(n.odometer_sigma_mps**2 + resolution_mps**2 / 6.0)
        return measured, sigma

    def gps_sample(self, truth: TruthSample) -> tuple[float, float, float]:
        """(latitude [deg], longitude [deg], altitude [m]) of the position ``gps_latency_s``
        ago, with the receiver's errors."""
        positions = self._positions_m
        if positions.maxlen is not None and len(positions) == positions.maxlen:
            position_m = positions[0]
        else:  # before the history is long enough (start): run the train back at its speed
            position_m = truth.position_m - truth.speed_mps * self.noise.gps_latency_s
        latitude, longitude, altitude = self.track_map.geodetic_at(position_m)
        north, east, up = self._gps.sample(truth.time_s, self._white(6), self.rng)
        self.gps_error_m = (north, east, up)
        self.multipath_events = self._gps.events
        degrees_per_m = 180.0 / (math.pi * EARTH_RADIUS_M)
        return (
            latitude + north * degrees_per_m,
            longitude + east * degrees_per_m / math.cos(math.radians(latitude)),
            altitude + up,
        )


class _GpsErrors:
    """The receiver's position error: Gauss–Markov per axis, white noise, multipath events."""

    def __init__(self, noise: SensorNoise) -> None:
        self.noise = noise
        self.events = 0
        self._correlated: list[float] | None = None
        self._time_s = 0.0
        self._multipath_until_s = -math.inf
        self._multipath_m = (0.0, 0.0)

    def sample(
        self, time_s: float, white: list[float], rng: np.random.Generator
    ) -> tuple[float, float, float]:
        """(north, east, up) error [m] at ``time_s`` from six standard normal draws."""
        n = self.noise
        sigmas = (
            n.gps_correlated_horizontal_sigma_m,
            n.gps_correlated_horizontal_sigma_m,
            n.gps_correlated_vertical_sigma_m,
        )
        dt_s = max(time_s - self._time_s, 0.0)
        if self._correlated is None:  # the stationary distribution
            self._correlated = [s * w for s, w in zip(sigmas, white[:3], strict=True)]
            dt_s = 0.0
        elif n.gps_correlation_time_s > 0.0:
            decay = math.exp(-dt_s / n.gps_correlation_time_s)
            drive = math.sqrt(1.0 - decay * decay)
            self._correlated = [
                decay * x + drive * s * w
                for x, s, w in zip(self._correlated, sigmas, white[:3], strict=True)
            ]
        else:
            self._correlated = [s * w for s, w in zip(sigmas, white[:3], strict=True)]
        self._time_s = time_s
        multipath_north, multipath_east = self._multipath(time_s, dt_s, rng)
        north, east, up = self._correlated
        horizontal, vertical = n.gps_horizontal_sigma_m, n.gps_vertical_sigma_m
        return (
            north + horizontal * white[3] + multipath_north,
            east + horizontal * white[4] + multipath_east,
            up + vertical * white[5],
        )

    def _multipath(
        self, time_s: float, dt_s: float, rng: np.random.Generator
    ) -> tuple[float, float]:
        n = self.noise
        if time_s < self._multipath_until_s:
            return self._multipath_m
        if n.gps_multipath_rate_per_s <= 0.0:
            return 0.0, 0.0
        chance, size, heading, length = rng.random(4).tolist()
        if chance >= -math.expm1(-n.gps_multipath_rate_per_s * dt_s):
            return 0.0, 0.0
        low_m, high_m = n.gps_multipath_offset_m
        offset_m = low_m + (high_m - low_m) * size
        angle = 2.0 * math.pi * heading
        low_s, high_s = n.gps_multipath_duration_s
        self._multipath_until_s = time_s + low_s + (high_s - low_s) * length
        self._multipath_m = (offset_m * math.cos(angle), offset_m * math.sin(angle))
        self.events += 1
        return self._multipath_m
