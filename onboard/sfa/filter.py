"""The along-track Kalman filter of the sensor-fusion algorithm (SFA, seed 002).

State ``x = [s, v, b, k, e]``: chainage s [m] (unwrapped on a ring: it keeps counting past
the origin), speed v [m/s], the longitudinal accelerometer bias b [m/s²], the odometer's scale
error k (its wheel's calibrated over real diameter minus 1: the odometer reads v (1 + k)) and
the GPS's along-track error e [m] (first-order Gauss–Markov, correlation time τ). The IMU is
the input: its forward specific force, minus the gravity component the track's gradient puts
along the body x axis (g sin θ, θ the pitch from the gradient at the estimated chainage), minus
the bias, drives

    s' = s + v dt + ½ (u − b) dt²,   v' = v + (u − b) dt,   b' = b,   k' = k,   e' = e^(−dt/τ) e.

Measurements (docs/sensors.md gives the sensors' errors they model):

- the odometer speed: the mean over its counting window W of the speed read through the scale
  error, h(x) = (1 + k)(v − (u − b) W/2), linearised; R = σ² from the packet;
- the GPS fix projected on the track map: the position ``gps_latency_s`` ago plus the GPS's
  correlated error, H = [1, −latency, 0, 0, 1], R = the white part's σ²;
- balise-group fixes, H = [1 0 0 0 0]: they calibrate the GPS's correlated error, which then
  carries their accuracy on for about τ.

Each odometer and GPS update is gated on its normalised innovation squared (NIS = y² / S, χ²
with one degree of freedom): above the gate it is rejected and counted. An IMU sample whose
acceleration (input less bias) lies outside the vehicle's envelope is gated out and counted
too, the prediction keeping the last input. The scale error is
learnt from the GPS and the balise groups against the IMU; without it a worn wheel's few per
mille would pull the position along by metres a kilometre. With no odometer and no GPS the
filter runs on the IMU alone, as the seed says, only worse: its σ grows and the health says
degraded.

The state lives in a :class:`filterpy.kalman.KalmanFilter` (``kf.x``, ``kf.P``). The prediction
is written by hand (two 5×5 products) because it runs at 100 Hz, and so are the scalar updates
(odometer at 20 Hz, GPS, fixes), filterpy's Joseph-form update without its copies and
allocations. Tests check the prediction against filterpy's ``predict`` to the last bits that
matter and the updates against filterpy's ``update`` bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from filterpy.kalman import KalmanFilter

from onboard.sfa._exceptions import NotInitialisedError
from protocol.units import GRAVITY_MPS2
from trackdb import TrackMap

__all__ = [
    "FilterConfig",
    "TrackKalmanFilter",
    "check_fix",
    "transition_matrices",
    "unwrap_near",
]

FloatArray = npt.NDArray[np.float64]

MATRIX_CACHE_SIZE = 256
"""Prediction steps whose matrices are kept (the cache starts again when full)."""
_matmul = np.matmul
_POSITION_H = np.array([[1.0, 0.0, 0.0, 0.0, 0.0]])
DIM_X = 5
"""State size: chainage, speed, accelerometer bias, odometer scale error, GPS error."""
UNKNOWN_INPUT_HOLD_S = 1.0
"""How long the train holds an acceleration no sensor measures [s] (a dead IMU's): over it the
speed's σ grows by the unknown input's σ × this time, as an acceleration held that long moves
the speed (the odometer then follows the URV's 1.8 m/s² of traction within its gate)."""


@dataclass(frozen=True, kw_only=True)
class FilterConfig:
    """Noise model and gates of :class:`TrackKalmanFilter` (SI units).

    Attributes
    ----------
    acceleration_noise_mps2 : float
        σ of the IMU's forward specific force as an input, white [m/s²].
    bias_random_walk_mps2_per_sqrt_s : float
        Random-walk intensity of the accelerometer bias [m/s²/√s].
    scale_random_walk_per_sqrt_s : float
        Random-walk intensity of the odometer's scale error [1/√s] (wear is slow; this lets the
        estimate follow a change of wheel or adhesion).
    initial_position_sigma_m, initial_speed_sigma_mps, initial_bias_sigma_mps2 : float
        σ of the state after a GROUND_TRUTH.
    initial_scale_sigma : float
        σ of the odometer's scale error after a GROUND_TRUTH (dimensionless).
    gps_sigma_m : float
        σ of the white part of a GPS fix's error, projected along the track [m].
    gps_correlated_sigma_m : float
        Stationary σ of the GPS's correlated (Gauss–Markov) along-track error [m].
    gps_correlation_time_s : float
        Correlation time of that error [s].
    gps_max_cross_track_m : float
        A fix further than this from the track is rejected before the filter sees it [m].
    odometer_sigma_floor_mps : float
        Lower bound on the odometer σ taken from its packet [m/s] (a zero σ would be fatal).
    gate_nis : float
        NIS above which an odometer update is rejected (χ²₁: 16 ≈ 4 σ).
    gps_gate_nis : float
        NIS above which a GPS update is rejected (χ²₁: 9 = 3 σ): multipath jumps of metres.
    gps_reanchor_after : int
        After this many GPS fixes rejected in a row the next one is taken whatever its
        innovation, the position's variance first widened to cover it: a filter that has
        drifted during an outage must not gate the GPS out for ever. Longer than a multipath
        event lasts (in fixes).
    gps_latency_s : float
        Age of the position a GPS fix reports when it arrives [s] (the receiver's datasheet
        latency): the fix is taken as a measurement of s − v·latency.
    odometer_window_s : float
        The interval the odometer counts its pulses over [s] (its sample period): its speed is
        the mean over that window, which lags the speed by half of it; 0 for a speed read at
        the instant.
    imu_max_acceleration_mps2, imu_max_deceleration_mps2 : float
        The along-track acceleration an IMU sample may give (its input less the estimated
        bias), forwards and backwards [m/s²]: the URV accelerates at up to about 1.9 m/s² and
        brakes at up to about 1.5 m/s²; 1 m/s² more covers the body's swings under wheel slip
        (1.5 m/s² within 20 ms on the bogie model), the sensor's noise and the bias's and the
        gradient's errors. A sample outside is gated out (counted, its input not taken). A
        sample of 2 m/s² or more with one corrupted byte (an exponent bit) can read anything up
        to the listener's 100 m/s² range check, as can one under 2 mm/s²; taken for 10 ms it
        would change the speed by up to 1 m/s. (Between the two, one byte reads under 2 m/s² or
        beyond 100 m/s².)
    """

    acceleration_noise_mps2: float = 0.05
    bias_random_walk_mps2_per_sqrt_s: float = 0.002
    scale_random_walk_per_sqrt_s: float = 2e-6
    initial_position_sigma_m: float = 1.0
    initial_speed_sigma_mps: float = 0.1
    initial_bias_sigma_mps2: float = 0.1
    initial_scale_sigma: float = 0.01
    gps_sigma_m: float = 0.3
    gps_correlated_sigma_m: float = 0.3
    gps_correlation_time_s: float = 60.0
    gps_max_cross_track_m: float = 50.0
    odometer_sigma_floor_mps: float = 0.01
    gate_nis: float = 16.0
    gps_gate_nis: float = 9.0
    gps_reanchor_after: int = 15
    gps_latency_s: float = 0.1
    odometer_window_s: float = 0.05
    imu_max_acceleration_mps2: float = 2.9
    imu_max_deceleration_mps2: float = 2.5


def transition_matrices(
    dt_s: float, config: FilterConfig
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """F (5×5), B (5×1) and Q (5×5) of one prediction over ``dt_s`` [s]."""
    half_dt2 = 0.5 * dt_s * dt_s
    decay = math.exp(-dt_s / config.gps_correlation_time_s)
    transition = np.eye(DIM_X)
    transition[0, 1], transition[0, 2], transition[1, 2] = dt_s, -half_dt2, -dt_s
    transition[4, 4] = decay
    control = np.array([[half_dt2], [dt_s], [0.0], [0.0], [0.0]])
    noise_input = np.array([half_dt2, dt_s, 0.0, 0.0, 0.0])
    process = np.outer(noise_input, noise_input) * config.acceleration_noise_mps2**2
    process[2, 2] += config.bias_random_walk_mps2_per_sqrt_s**2 * dt_s
    process[3, 3] += config.scale_random_walk_per_sqrt_s**2 * dt_s
    process[4, 4] += config.gps_correlated_sigma_m**2 * (1.0 - decay * decay)
    return transition, control, process


def unwrap_near(track_map: TrackMap, chainage_m: float, reference_m: float) -> float:
    """A chainage on the line [m] moved to the lap of an unwrapped ``reference_m`` [m]: the
    nearest such position on a ring, the chainage itself otherwise."""
    if not track_map.line.ring:
        return chainage_m
    length = track_map.length_m
    delta = (chainage_m - track_map.normalise(reference_m) + 0.5 * length) % length
    return reference_m + delta - 0.5 * length


def check_fix(chainage_m: float, sigma_m: float, epoch_s: float) -> None:
    """Raise ``ValueError`` unless a balise fix is finite with a positive σ."""
    if not (math.isfinite(chainage_m) and math.isfinite(epoch_s) and 0.0 < sigma_m < math.inf):
        raise ValueError(f"balise fix ({chainage_m}, {sigma_m}, {epoch_s}) is not valid")


class TrackKalmanFilter:
    """Chainage, speed, accelerometer bias and odometer scale error along one line.

    Parameters
    ----------
    track_map : TrackMap
        The line: gradients for the gravity term, geodesy for GPS projection.
    config : FilterConfig
        Noise model and gates.
    """

    def __init__(self, track_map: TrackMap, config: FilterConfig | None = None) -> None:
        self.track_map = track_map
        self.config = config or FilterConfig()
        self.kf = KalmanFilter(dim_x=DIM_X, dim_z=1)
        self.initialised = False
        self.epoch_s = 0.0
        self.last_input_mps2 = 0.0
        self.unknown_input_sigma_mps2: float | None = None
        """σ of an acceleration no sensor measures [m/s²]: set while the IMU is dead, so that the
        prediction (then at constant speed) admits the train's braking and traction and the
        odometer's speeds are not gated out as the train slows or speeds up."""
        self.rejected = {"imu": 0, "odometer": 0, "gps": 0}
        self.accepted = {"imu": 0, "odometer": 0, "gps": 0, "fix": 0}
        self.reanchored = 0
        """GPS fixes taken after ``gps_reanchor_after`` rejections in a row."""
        self._gps_rejections_in_row = 0
        self._matrices_dt_s = -1.0
        # The matrices by step: epochs are STROBE + k / rate, so their differences take a few
        # dozen float values around the IMU period, not one; each is worked out once.
        self._matrices: dict[float, tuple[FloatArray, FloatArray, FloatArray]] = {}
        self._transition = np.eye(DIM_X)
        self._transition_t = np.eye(DIM_X)
        self._process = np.zeros((DIM_X, DIM_X))
        self._identity = np.eye(DIM_X)

    # -- state -----------------------------------------------------------------------------

    def initialise(self, chainage_m: float, speed_mps: float, epoch_s: float) -> None:
        """(Re)start from a GROUND_TRUTH: chainage [m], speed [m/s], at ``epoch_s`` [s]."""
        c = self.config
        self.kf.x = np.array([[chainage_m], [speed_mps], [0.0], [0.0], [0.0]])
        self.kf.P = np.diag(
            [
                c.initial_position_sigma_m**2,
                c.initial_speed_sigma_mps**2,
                c.initial_bias_sigma_mps2**2,
                c.initial_scale_sigma**2,
                c.gps_correlated_sigma_m**2,
            ]
        )
        self.epoch_s = epoch_s
        self.last_input_mps2 = 0.0
        self._gps_rejections_in_row = 0
        self.initialised = True

    def _require(self) -> None:
        if not self.initialised:
            raise NotInitialisedError("the filter has had no GROUND_TRUTH")

    @property
    def chainage_m(self) -> float:
        """Unwrapped chainage estimate [m]."""
        self._require()
        return float(self.kf.x[0, 0])

    @property
    def speed_mps(self) -> float:
        self._require()
        return float(self.kf.x[1, 0])

    @property
    def bias_mps2(self) -> float:
        self._require()
        return float(self.kf.x[2, 0])

    @property
    def odometer_scale_error(self) -> float:
        """The odometer's estimated scale error k (it reads v (1 + k)), dimensionless."""
        self._require()
        return float(self.kf.x[3, 0])

    @property
    def gps_error_m(self) -> float:
        """The GPS's estimated correlated along-track error [m] (a fix reads s + e)."""
        self._require()
        return float(self.kf.x[4, 0])

    @property
    def position_sigma_m(self) -> float:
        self._require()
        return math.sqrt(max(float(self.kf.P[0, 0]), 0.0))

    @property
    def speed_sigma_mps(self) -> float:
        self._require()
        return math.sqrt(max(float(self.kf.P[1, 1]), 0.0))

    # -- prediction ------------------------------------------------------------------------

    def forward_specific_force_to_input(self, acc_x_mps2: float) -> float:
        """Along-track acceleration [m/s²] (bias not removed) from the forward specific force:
        the gravity component of the gradient at the estimated chainage is taken out."""
        gradient = self.track_map.gradient_permille(float(self.kf.x[0, 0]))
        return acc_x_mps2 - GRAVITY_MPS2 * math.sin(math.atan(gradient / 1000.0))

    def imu(self, epoch_s: float, acc_x_mps2: float) -> bool:
        """Predict to ``epoch_s`` with this IMU sample's forward specific force as the input;
        False when the sample is gated out (an acceleration outside the vehicle's envelope):
        the prediction then keeps the last input."""
        self._require()
        input_mps2 = self.forward_specific_force_to_input(acc_x_mps2)
        config = self.config
        acceleration = input_mps2 - float(self.kf.x[2, 0])
        accepted = (
            -config.imu_max_deceleration_mps2 <= acceleration <= config.imu_max_acceleration_mps2
        )
        if accepted:
            self.last_input_mps2 = input_mps2
            self.accepted["imu"] += 1
        else:
            self.rejected["imu"] += 1
        self.predict_to(epoch_s)
        return accepted

    def predict_to(self, epoch_s: float) -> None:
        """Predict from the filter's epoch to ``epoch_s`` with the last input; never backwards."""
        dt_s = epoch_s - self.epoch_s
        if dt_s <= 0.0:
            return
        self.predict(dt_s, self.last_input_mps2)
        self.epoch_s = epoch_s

    def predict(self, dt_s: float, input_mps2: float) -> None:
        """One prediction over ``dt_s`` [s] with the along-track input [m/s²] (fast path)."""
        if dt_s != self._matrices_dt_s:
            matrices = self._matrices.get(dt_s)
            if matrices is None:
                if len(self._matrices) >= MATRIX_CACHE_SIZE:
                    self._matrices.clear()
                transition, _, process = transition_matrices(dt_s, self.config)
                matrices = (transition, transition.T.copy(), process)
                self._matrices[dt_s] = matrices
            self._transition, self._transition_t, self._process = matrices
            self._matrices_dt_s = dt_s
        x = self.kf.x
        position, speed, bias = float(x[0, 0]), float(x[1, 0]), float(x[2, 0])
        acceleration = input_mps2 - bias
        x[0, 0] = position + speed * dt_s + 0.5 * acceleration * dt_s * dt_s
        x[1, 0] = speed + acceleration * dt_s
        x[4, 0] *= self._transition[4, 4]
        self.kf.P = self._transition @ self.kf.P @ self._transition_t + self._process
        if self.unknown_input_sigma_mps2 is not None:
            # Continuous white acceleration of density σ² × UNKNOWN_INPUT_HOLD_S: the speed's
            # variance grows by that much a second whatever the step. Drawn afresh each step
            # (the speed's variance then grew by σ² dt², 0.11 m/s in a second at 20 Hz), a
            # traction held at 1.3–1.8 m/s² left the speed lagging past the odometer's gate,
            # and once gated out the error outgrew σ until the traction ended.
            density = self.unknown_input_sigma_mps2**2 * UNKNOWN_INPUT_HOLD_S
            dt2 = dt_s * dt_s
            self.kf.P[0, 0] += density * dt2 * dt_s / 3.0
            self.kf.P[0, 1] += density * dt2 / 2.0
            self.kf.P[1, 0] += density * dt2 / 2.0
            self.kf.P[1, 1] += density * dt_s

    # -- measurements ----------------------------------------------------------------------

    def _gated_update(
        self, z: float, h: FloatArray, variance: float, sensor: str, gate_nis: float
    ) -> bool:
        innovation, gain_numerator, innovation_variance = self._innovation(z, h, variance)
        if innovation * innovation > gate_nis * innovation_variance:
            self.rejected[sensor] += 1
            return False
        self._apply_update(innovation, gain_numerator, innovation_variance, h, variance)
        self.accepted[sensor] += 1
        return True

    def _update(self, z: float, h: FloatArray, variance: float) -> None:
        """One scalar update of measurement ``z`` [its unit] through ``h`` (1×5) with variance
        R [its unit²], not gated."""
        self._apply_update(*self._innovation(z, h, variance), h, variance)

    def _innovation(
        self, z: float, h: FloatArray, variance: float
    ) -> tuple[float, FloatArray, float]:
        """y = z − h x, P hᵀ (5×1) and S = h P hᵀ + R of a scalar measurement."""
        kf = self.kf
        innovation = z - float(_matmul(h, kf.x)[0, 0])
        gain_numerator = _matmul(kf.P, h.T)
        return innovation, gain_numerator, float(_matmul(h, gain_numerator)[0, 0]) + variance

    def _apply_update(
        self,
        innovation: float,
        gain_numerator: FloatArray,
        innovation_variance: float,
        h: FloatArray,
        variance: float,
    ) -> None:
        """The update of x and P from the innovation y, P hᵀ (5×1) and S = h P hᵀ + R.

        filterpy's ``KalmanFilter.update`` step by step (Joseph form), its operands kept as they
        are where they are sums, so that x and P come out bit for bit the same (a test checks
        it): the products with a sum stay BLAS products (``numpy.matmul``, the same bits as
        filterpy's ``numpy.dot``); the products by a 1×1 matrix (S⁻¹, R, y), one multiplication
        an element, are broadcast instead. Left out is what no one here reads: the copies
        filterpy keeps of z, x and P, its reshaping, the arrays made for z and R at every call,
        and y, P hᵀ and S worked out a second time after the gate (docs/perf.md, "Sensor
        fusion").
        """
        kf = self.kf
        gain = gain_numerator * (1.0 / innovation_variance)
        kf.x = kf.x + gain * innovation
        i_kh = self._identity - gain * h
        kf.P = _matmul(_matmul(i_kh, kf.P), i_kh.T) + (gain * variance) * gain.T

    def odometer(self, epoch_s: float, speed_mps: float, sigma_mps: float) -> bool:
        """Update with an odometer speed [m/s] and its σ; False when gated out."""
        self._require()
        self.predict_to(epoch_s)
        config = self.config
        sigma = max(sigma_mps, config.odometer_sigma_floor_mps)
        x = self.kf.x
        speed, bias, scale = float(x[1, 0]), float(x[2, 0]), 1.0 + float(x[3, 0])
        # The pulses counted over the window give its mean speed: the speed now less half the
        # window's worth of the acceleration (u − b).
        half_window_s = 0.5 * config.odometer_window_s
        mean_speed = speed - (self.last_input_mps2 - bias) * half_window_s
        h = np.array([[0.0, scale, scale * half_window_s, mean_speed, 0.0]])
        # filterpy takes the innovation as z − H x; the measurement is h(x) = (1 + k) × the mean
        # speed, not H x, so the linearisation's offset H x − h(x) is added to z.
        offset = float((h @ x)[0, 0]) - scale * mean_speed
        return self._gated_update(speed_mps + offset, h, sigma * sigma, "odometer", config.gate_nis)

    def unwrap_near_estimate(self, chainage_m: float) -> float:
        """A chainage on the line [m] moved to the lap of the estimate (identity off a ring)."""
        return unwrap_near(self.track_map, chainage_m, float(self.kf.x[0, 0]))

    def gps(self, epoch_s: float, latitude_deg: float, longitude_deg: float) -> bool:
        """Update with a GPS fix projected on the track; False when it is off the track or
        gated out."""
        self._require()
        self.predict_to(epoch_s)
        try:
            projection = self.track_map.project(
                latitude_deg, longitude_deg, near_m=float(self.kf.x[0, 0])
            )
        except ValueError:
            self.rejected["gps"] += 1
            return False
        if abs(projection.cross_track_m) > self.config.gps_max_cross_track_m:
            self.rejected["gps"] += 1
            return False
        z = self.unwrap_near_estimate(projection.chainage_m)
        config = self.config
        # The fix is where the train was gps_latency_s ago, plus the GPS's correlated error.
        h = np.array([[1.0, -config.gps_latency_s, 0.0, 0.0, 1.0]])
        variance = config.gps_sigma_m**2
        if self._gps_rejections_in_row >= config.gps_reanchor_after:
            innovation = z - float(_matmul(h, self.kf.x)[0, 0])
            self.kf.P[0, 0] += innovation * innovation
            self.reanchored += 1
        if self._gated_update(z, h, variance, "gps", config.gps_gate_nis):
            self._gps_rejections_in_row = 0
            return True
        self._gps_rejections_in_row += 1
        return False

    def fix(self, chainage_m: float, sigma_m: float, epoch_s: float) -> None:
        """A balise-group fix: chainage on the line [m], its σ [m], at ``epoch_s`` [s].

        Not gated: a balise group is the reference the other sensors are judged against.
        """
        self._require()
        self.predict_to(epoch_s)
        z = self.unwrap_near_estimate(chainage_m)
        self._update(z, _POSITION_H, max(sigma_m, 1e-3) ** 2)
        self.accepted["fix"] += 1
