"""The along-track Kalman filter of the sensor-fusion algorithm (SFA, seed 002).

State ``x = [s, v, b]``: chainage s [m] (unwrapped on a ring: it keeps counting past the
origin), speed v [m/s] and the longitudinal accelerometer bias b [m/s²]. The IMU is the input:
its forward specific force, minus the gravity component the track's gradient puts along the body
x axis (g sin θ, θ the pitch from the gradient at the estimated chainage), minus the bias, drives

    s' = s + v dt + ½ (u − b) dt²,    v' = v + (u − b) dt,    b' = b.

Measurements: the odometer/radar speed (H = [0 1 0], R = σ² from the packet), the GPS fix
projected on the track map (H = [1 0 0]), and balise-group fixes. Each odometer and GPS update is
gated on its normalised innovation squared (NIS = y² / S, χ² with one degree of freedom): above
the gate it is rejected and counted. With no odometer and no GPS the filter runs on the IMU
alone, as the seed says, only worse: its σ grows and the health says degraded.

The prediction is written by hand (two 3×3 products) because it runs at 100 Hz; the updates go
through :class:`filterpy.kalman.KalmanFilter`. A test checks the hand-written prediction against
filterpy's ``predict`` to the last bits that matter.
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
_ODO_H = np.array([[0.0, 1.0, 0.0]])
_POSITION_H = np.array([[1.0, 0.0, 0.0]])


@dataclass(frozen=True, kw_only=True)
class FilterConfig:
    """Noise model and gates of :class:`TrackKalmanFilter` (SI units).

    Attributes
    ----------
    acceleration_noise_mps2 : float
        σ of the IMU's forward specific force as an input, white [m/s²].
    bias_random_walk_mps2_per_sqrt_s : float
        Random-walk intensity of the accelerometer bias [m/s²/√s].
    initial_position_sigma_m, initial_speed_sigma_mps, initial_bias_sigma_mps2 : float
        σ of the state after a GROUND_TRUTH.
    gps_sigma_m : float
        σ of a GPS fix projected along the track [m].
    gps_max_cross_track_m : float
        A fix further than this from the track is rejected before the filter sees it [m].
    odometer_sigma_floor_mps : float
        Lower bound on the odometer σ taken from its packet [m/s] (a zero σ would be fatal).
    gate_nis : float
        NIS above which an odometer or GPS update is rejected (χ²₁: 16 ≈ 4 σ).
    """

    acceleration_noise_mps2: float = 0.05
    bias_random_walk_mps2_per_sqrt_s: float = 0.002
    initial_position_sigma_m: float = 1.0
    initial_speed_sigma_mps: float = 0.1
    initial_bias_sigma_mps2: float = 0.1
    gps_sigma_m: float = 3.0
    gps_max_cross_track_m: float = 50.0
    odometer_sigma_floor_mps: float = 0.01
    gate_nis: float = 16.0


def transition_matrices(
    dt_s: float, config: FilterConfig
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """F (3×3), B (3×1) and Q (3×3) of one prediction over ``dt_s`` [s]."""
    half_dt2 = 0.5 * dt_s * dt_s
    transition = np.array([[1.0, dt_s, -half_dt2], [0.0, 1.0, -dt_s], [0.0, 0.0, 1.0]])
    control = np.array([[half_dt2], [dt_s], [0.0]])
    noise_input = np.array([half_dt2, dt_s, 0.0])
    process = np.outer(noise_input, noise_input) * config.acceleration_noise_mps2**2
    process[2, 2] += config.bias_random_walk_mps2_per_sqrt_s**2 * dt_s
    return transition, control, process


def _scalar_inverse(matrix: FloatArray) -> FloatArray:
    """The inverse of a 1×1 matrix."""
    return np.array([[1.0 / float(matrix[0, 0])]])


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
    """Chainage, speed and accelerometer bias along one line.

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
        self.kf = KalmanFilter(dim_x=3, dim_z=1)
        # Every update is scalar: filterpy's hook for the innovation's inverse takes the
        # reciprocal instead of numpy.linalg.inv (the same value, in a fraction of the time).
        self.kf.inv = _scalar_inverse
        self.initialised = False
        self.epoch_s = 0.0
        self.last_input_mps2 = 0.0
        self.rejected = {"odometer": 0, "gps": 0}
        self.accepted = {"odometer": 0, "gps": 0, "fix": 0}
        self._matrices_dt_s = -1.0
        # The matrices by step: epochs are STROBE + k / rate, so their differences take a few
        # dozen float values around the IMU period, not one; each is worked out once.
        self._matrices: dict[float, tuple[FloatArray, FloatArray, FloatArray]] = {}
        self._transition = np.eye(3)
        self._transition_t = np.eye(3)
        self._process = np.zeros((3, 3))

    # -- state -----------------------------------------------------------------------------

    def initialise(self, chainage_m: float, speed_mps: float, epoch_s: float) -> None:
        """(Re)start from a GROUND_TRUTH: chainage [m], speed [m/s], at ``epoch_s`` [s]."""
        c = self.config
        self.kf.x = np.array([[chainage_m], [speed_mps], [0.0]])
        self.kf.P = np.diag(
            [
                c.initial_position_sigma_m**2,
                c.initial_speed_sigma_mps**2,
                c.initial_bias_sigma_mps2**2,
            ]
        )
        self.epoch_s = epoch_s
        self.last_input_mps2 = 0.0
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

    def imu(self, epoch_s: float, acc_x_mps2: float) -> None:
        """Predict to ``epoch_s`` with this IMU sample's forward specific force as the input."""
        self._require()
        self.last_input_mps2 = self.forward_specific_force_to_input(acc_x_mps2)
        self.predict_to(epoch_s)

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
        self.kf.P = self._transition @ self.kf.P @ self._transition_t + self._process

    # -- measurements ----------------------------------------------------------------------

    def _gated_update(self, z: float, h: FloatArray, variance: float, sensor: str) -> bool:
        kf = self.kf
        innovation = z - float((h @ kf.x)[0, 0])
        innovation_variance = float((h @ kf.P @ h.T)[0, 0]) + variance
        if innovation * innovation > self.config.gate_nis * innovation_variance:
            self.rejected[sensor] += 1
            return False
        kf.update(np.array([[z]]), R=np.array([[variance]]), H=h)
        self.accepted[sensor] += 1
        return True

    def odometer(self, epoch_s: float, speed_mps: float, sigma_mps: float) -> bool:
        """Update with an odometer speed [m/s] and its σ; False when gated out."""
        self._require()
        self.predict_to(epoch_s)
        sigma = max(sigma_mps, self.config.odometer_sigma_floor_mps)
        return self._gated_update(speed_mps, _ODO_H, sigma * sigma, "odometer")

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
        return self._gated_update(z, _POSITION_H, self.config.gps_sigma_m**2, "gps")

    def fix(self, chainage_m: float, sigma_m: float, epoch_s: float) -> None:
        """A balise-group fix: chainage on the line [m], its σ [m], at ``epoch_s`` [s].

        Not gated: a balise group is the reference the other sensors are judged against.
        """
        self._require()
        self.predict_to(epoch_s)
        z = self.unwrap_near_estimate(chainage_m)
        self.kf.update(np.array([[z]]), R=np.array([[max(sigma_m, 1e-3) ** 2]]), H=_POSITION_H)
        self.accepted["fix"] += 1
