"""Braking curves and supervision limits of SUBSET-026 §3.13.8–3.13.9 (DOMAIN.md §1.1–1.5).

Distances here are **distances before the target** [m]: a limit at distance d is reached when
the relevant front end is d short of the target. For an estimated speed V_est [m/s]:

- ceiling margins (§1.1): dV = min(dV_min + C·(V_MRSP − V_min), dV_max) above V_min, else
  dV_min, with C = (dV_max − dV_min)/(V_max − V_min); for dV_ebi, dV_sbi and dV_warning.
- EBD: speed² = V_t² + 2∫A_safe, 0 at the SvL; for an MRSP target it crosses
  V_target + dV_ebi(V_target) at the target. SBD: the same with A_expected, 0 at the EoA.
- EBI (EBD-based targets)::

      V_bec = max(V_est + V_δ0 + V_δ1, V_target) + V_δ2
      D_bec = max(V_est + V_δ0 + V_δ1/2, V_target)·T_traction
              + (max(V_est + V_δ0 + V_δ1, V_target) + V_δ2/2)·T_berem
      d_EBI = d_EBD(V_bec) + D_bec

  with V_δ0 = V_ura(V_est) (0 if Q_NVINHSMICPERM), V_δ1 = A_est1·T_traction,
  V_δ2 = A_est2·T_berem, A_est1 = max(A_est, 0), A_est2 = min(max(A_est, 0), 0.4).
- SBI1 = d_SBD(V_est) + V_est·T_bs1 (EoA); SBI2 = d_EBI + V_est·T_bs2 (SvL, MRSP targets).
- W = SBI + V_est·T_warning, P = SBI + V_est·T_driver, I = P + V_est·T_indication with
  T_indication = max(0.8·T_bs, 5 s) + T_driver (5 s + T_driver with SB feedback).
- Times: T_traction = max(T_traction_cut_off − (T_warning + T_bs2), 0) when traction cut-off
  is implemented; T_berem = max(T_be − T_traction, 0); T_bs1 = T_bs2 = T_bs with a service
  brake command, 0 without.

Every limit's distance grows with the speed, so the **speed of a limit at a distance** is the
highest speed whose limit lies at that distance or further on, found by bisection (exact for
EBD and SBD). The guidance curve (GUI) is not modelled (Q_NVGUIPERM is No by default).
V_ura comes from SUBSET-041 §5.3.1.2 (DOMAIN.md §6): 2 km/h to 30 km/h, then linear to 12 km/h
at 500 km/h.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import numpy.typing as npt

from onboard.etcs._exceptions import EtcsInputError
from onboard.etcs.deceleration import (
    DecelerationProfile,
    brake_safe_deceleration_mps2,
)
from onboard.etcs.values import (
    FIXED_VALUES,
    NATIONAL_DEFAULTS,
    URV_TRAIN_DATA,
    BrakeModelType,
    FixedValues,
    NationalValues,
    TrainData,
)
from onboard.runtime.compiled import compiled
from protocol import units
from protocol.units import MPS_PER_KMH
from trackdb import TrackMap

__all__ = [
    "DEFAULT_LOOKBACK_M",
    "SPEED_TOLERANCE_MPS",
    "BrakingCurve",
    "BrakingModel",
    "BrakingTimes",
    "Limit",
    "LimitDistances",
    "Target",
    "TargetKind",
    "TargetLimits",
    "braking_times",
    "ceiling_margin_mps",
    "dv_ebi_mps",
    "dv_sbi_mps",
    "dv_warning_mps",
    "speed_measurement_accuracy_mps",
]

DEFAULT_LOOKBACK_M = 10_000.0
"""How far before a target [m] its deceleration profile is read when no window is given."""
SPEED_TOLERANCE_MPS = 1e-6
"""How closely [m/s] a limit's speed at a distance is found."""
FloatArray = npt.NDArray[np.float64]
_SPEED_SEARCH_MPS = 150.0
_SPEED_SEARCH_MAX_MPS = 1e4


def ceiling_margin_mps(
    v_mrsp_mps: float, dv_min_mps: float, dv_max_mps: float, v_min_mps: float, v_max_mps: float
) -> float:
    """A ceiling-speed margin [m/s] at the MRSP (or LOA) speed [m/s] (§3.13.9.2.3–.7)."""
    if v_mrsp_mps <= v_min_mps:
        return dv_min_mps
    slope = (dv_max_mps - dv_min_mps) / (v_max_mps - v_min_mps)
    return min(dv_min_mps + slope * (v_mrsp_mps - v_min_mps), dv_max_mps)


def dv_ebi_mps(v_mrsp_mps: float, fixed: FixedValues = FIXED_VALUES) -> float:
    """dV_ebi [m/s]: 7.5 km/h up to 110 km/h, then linear to 15 km/h at 210 km/h."""
    f = fixed
    return ceiling_margin_mps(
        v_mrsp_mps, f.dv_ebi_min_mps, f.dv_ebi_max_mps, f.v_ebi_min_mps, f.v_ebi_max_mps
    )


def dv_sbi_mps(v_mrsp_mps: float, fixed: FixedValues = FIXED_VALUES) -> float:
    """dV_sbi [m/s]: 5.5 km/h up to 110 km/h, then linear to 10 km/h at 210 km/h."""
    f = fixed
    return ceiling_margin_mps(
        v_mrsp_mps, f.dv_sbi_min_mps, f.dv_sbi_max_mps, f.v_sbi_min_mps, f.v_sbi_max_mps
    )


def dv_warning_mps(v_mrsp_mps: float, fixed: FixedValues = FIXED_VALUES) -> float:
    """dV_warning [m/s]: 4 km/h up to 110 km/h, then linear to 5 km/h at 140 km/h."""
    f = fixed
    return ceiling_margin_mps(
        v_mrsp_mps,
        f.dv_warning_min_mps,
        f.dv_warning_max_mps,
        f.v_warning_min_mps,
        f.v_warning_max_mps,
    )


_URA_MIN_MPS, _URA_MAX_MPS = 2.0 * MPS_PER_KMH, 12.0 * MPS_PER_KMH
_URA_FROM_MPS, _URA_TO_MPS = 30.0 * MPS_PER_KMH, 500.0 * MPS_PER_KMH
_URA_SLOPE = (_URA_MAX_MPS - _URA_MIN_MPS) / (_URA_TO_MPS - _URA_FROM_MPS)
"""V_ura's line, computed as :func:`ceiling_margin_mps` computes it (same operations, same bits)."""


def speed_measurement_accuracy_mps(speed_mps: float) -> float:
    """V_ura [m/s]: 2 km/h up to 30 km/h, linear to 12 km/h at 500 km/h, 12 km/h above."""
    return ceiling_margin_mps(speed_mps, _URA_MIN_MPS, _URA_MAX_MPS, _URA_FROM_MPS, _URA_TO_MPS)


class BrakingCurve:
    """A deceleration curve to a target: speed² = V_t² + 2∫A over the distance before it.

    Parameters
    ----------
    profile : DecelerationProfile
        Deceleration [m/s²] by front-end location [m].
    target_m : float
        The target's location [m]; the curve reaches ``target_speed_mps`` there.
    target_speed_mps : float
        Speed of the curve at the target [m/s], ≥ 0.
    """

    __slots__ = ("_arrays", "_beyond_mps2", "_bands_m", "_decelerations", "_squares", "target_m")

    def __init__(
        self, profile: DecelerationProfile, *, target_m: float, target_speed_mps: float
    ) -> None:
        if not (math.isfinite(target_m) and math.isfinite(target_speed_mps)):
            raise EtcsInputError("a braking curve needs a finite target and target speed")
        if target_speed_mps < 0:
            raise EtcsInputError("a braking curve's target speed must not be negative")
        self.target_m = target_m
        # Bands in distance before the target: band k spans [bands[k], bands[k+1]), the last
        # one without end. Walking back from the target, each profile start passed changes the
        # deceleration to the value before that start.
        starts, values = profile.starts_m, profile.values_mps2
        bands = [0.0]
        decelerations = [profile.at(math.nextafter(target_m, -math.inf))]
        for index in range(len(starts) - 1, 0, -1):
            if starts[index] < target_m:
                bands.append(target_m - starts[index])
                decelerations.append(values[index - 1])
        squares = [target_speed_mps**2]
        for k in range(1, len(bands)):
            squares.append(squares[-1] + 2.0 * decelerations[k - 1] * (bands[k] - bands[k - 1]))
        self._bands_m = bands
        self._decelerations = decelerations
        self._squares = squares
        self._beyond_mps2 = profile.at(target_m)
        self._arrays: CurveArrays | None = None

    def speed_mps(self, distance_m: float) -> float:
        """The curve's speed [m/s] at ``distance_m`` [m] before the target (< 0: beyond it)."""
        if distance_m < 0.0:
            square = self._squares[0] - 2.0 * self._beyond_mps2 * -distance_m
        else:
            k = bisect.bisect_right(self._bands_m, distance_m) - 1
            square = self._squares[k] + 2.0 * self._decelerations[k] * (
                distance_m - self._bands_m[k]
            )
        return math.sqrt(max(square, 0.0))

    def distance_m(self, speed_mps: float) -> float:
        """Distance [m] before the target where the curve has ``speed_mps`` (< 0: beyond it)."""
        square = speed_mps * speed_mps
        if square < self._squares[0]:
            return -(self._squares[0] - square) / (2.0 * self._beyond_mps2)
        k = bisect.bisect_right(self._squares, square) - 1
        return self._bands_m[k] + (square - self._squares[k]) / (2.0 * self._decelerations[k])

    def arrays(self) -> CurveArrays:
        """The curve as :func:`_curve_distance` reads it: its squares, bands and decelerations
        as arrays, and twice the deceleration beyond the target (made once, on first use)."""
        if self._arrays is None:
            self._arrays = (
                np.array(self._squares),
                np.array(self._bands_m),
                np.array(self._decelerations),
                2.0 * self._beyond_mps2,
            )
        return self._arrays


@dataclass(frozen=True, kw_only=True)
class BrakingTimes:
    """The times [s] of the supervision limits (§3.13.9.3)."""

    t_be_s: float
    t_bs_s: float
    t_bs1_s: float
    t_bs2_s: float
    t_traction_s: float
    t_berem_s: float
    t_warning_s: float
    t_driver_s: float
    t_indication_s: float


def braking_times(
    train: TrainData,
    *,
    national: NationalValues = NATIONAL_DEFAULTS,
    fixed: FixedValues = FIXED_VALUES,
    target_speed_mps: float = 0.0,
) -> BrakingTimes:
    """The limit times for a target of that speed (the conversion model's ×1.2 above 0)."""
    t_eb, t_sb = train.t_brake_emergency_s, train.t_brake_service_s
    t_be = t_eb
    if train.brake_model is BrakeModelType.LAMBDA:
        if target_speed_mps > 0:
            t_eb, t_sb = 1.2 * t_eb, 1.2 * t_sb
        t_be = national.kt_int * t_eb
    t_bs = t_sb
    t_bs12 = t_bs if train.service_brake_available else 0.0
    t_traction = train.t_traction_cut_off_s
    if train.traction_cut_off_implemented:
        t_traction = max(t_traction - (fixed.t_warning_s + t_bs12), 0.0)
    if national.service_brake_feedback:
        t_indication = 5.0 + fixed.t_driver_s
    else:
        t_indication = max(0.8 * t_bs, 5.0) + fixed.t_driver_s
    return BrakingTimes(
        t_be_s=t_be,
        t_bs_s=t_bs,
        t_bs1_s=t_bs12,
        t_bs2_s=t_bs12,
        t_traction_s=t_traction,
        t_berem_s=max(t_be - t_traction, 0.0),
        t_warning_s=fixed.t_warning_s,
        t_driver_s=fixed.t_driver_s,
        t_indication_s=t_indication,
    )


class TargetKind(StrEnum):
    """What a braking target is: the EoA (SBD-based), the SvL or an MRSP decrease (EBD-based)."""

    END_OF_AUTHORITY = "eoa"
    SUPERVISED_LOCATION = "svl"
    SPEED_DECREASE = "mrsp"


class Limit(StrEnum):
    """The curves and supervision limits of a target."""

    EBD = "ebd"
    SBD = "sbd"
    EBI = "ebi"
    SBI1 = "sbi1"
    SBI2 = "sbi2"
    WARNING = "w"
    PERMITTED = "p"
    INDICATION = "i"


@dataclass(frozen=True)
class Target:
    """A braking target: its kind, its location [m] and its speed [m/s] (0 for EoA and SvL)."""

    kind: TargetKind
    location_m: float
    speed_mps: float = 0.0

    @property
    def ebd_based(self) -> bool:
        """EBD-based targets (SvL, MRSP) are supervised on the max-safe front end."""
        return self.kind is not TargetKind.END_OF_AUTHORITY


@dataclass(frozen=True, kw_only=True)
class LimitDistances:
    """Every supervision limit of one target at one speed, as distances before it [m].

    ``emergency_brake_intervention_m`` is None for the EoA, which has no EBI.
    """

    emergency_brake_intervention_m: float | None
    service_brake_intervention_m: float
    warning_m: float
    permitted_m: float
    indication_m: float


class TargetLimits:
    """The braking curve and the supervision limits of one target."""

    __slots__ = ("_accuracy_compensated", "_a_est2_max", "curve", "target", "times")

    def __init__(
        self,
        target: Target,
        curve: BrakingCurve,
        times: BrakingTimes,
        *,
        fixed: FixedValues = FIXED_VALUES,
        national: NationalValues = NATIONAL_DEFAULTS,
    ) -> None:
        self.target = target
        self.curve = curve
        self.times = times
        self._a_est2_max = fixed.a_est2_max_mps2
        self._accuracy_compensated = not national.inhibit_speed_accuracy_compensation

    @property
    def limits(self) -> tuple[Limit, ...]:
        """The limits this target has."""
        if self.target.ebd_based:
            return (
                Limit.EBD,
                Limit.EBI,
                Limit.SBI2,
                Limit.WARNING,
                Limit.PERMITTED,
                Limit.INDICATION,
            )
        return Limit.SBD, Limit.SBI1, Limit.WARNING, Limit.PERMITTED, Limit.INDICATION

    def _emergency_intervention_m(self, speed_mps: float, acceleration_mps2: float) -> float:
        t = self.times
        v_target = self.target.speed_mps
        a_est1 = max(acceleration_mps2, 0.0)
        a_est2 = min(a_est1, self._a_est2_max)
        v_delta0 = speed_measurement_accuracy_mps(speed_mps) if self._accuracy_compensated else 0.0
        v_delta1 = a_est1 * t.t_traction_s
        v_delta2 = a_est2 * t.t_berem_s
        v_bec = max(speed_mps + v_delta0 + v_delta1, v_target) + v_delta2
        d_bec = (
            max(speed_mps + v_delta0 + v_delta1 / 2.0, v_target) * t.t_traction_s
            + (max(speed_mps + v_delta0 + v_delta1, v_target) + v_delta2 / 2.0) * t.t_berem_s
        )
        return self.curve.distance_m(v_bec) + d_bec

    def _limit_m(self, limit: Limit, v: float, acceleration_mps2: float) -> float:
        """A limit's distance for a checked limit and speed: the arithmetic alone."""
        t = self.times
        if limit is Limit.EBD or limit is Limit.SBD:
            return self.curve.distance_m(v)
        if self.target.ebd_based:
            ebi = self._emergency_intervention_m(v, acceleration_mps2)
            if limit is Limit.EBI:
                return ebi
            sbi = ebi + v * t.t_bs2_s
        else:
            sbi = self.curve.distance_m(v) + v * t.t_bs1_s
        if limit is Limit.SBI1 or limit is Limit.SBI2:
            return sbi
        if limit is Limit.WARNING:
            return sbi + v * t.t_warning_s
        permitted = sbi + v * t.t_driver_s
        return permitted if limit is Limit.PERMITTED else permitted + v * t.t_indication_s

    def distances(self, speed_mps: float, *, acceleration_mps2: float = 0.0) -> LimitDistances:
        """All limits at the estimated speed [m/s] and acceleration [m/s²], before the target."""
        _check_speed(speed_mps, acceleration_mps2)
        t = self.times
        v = speed_mps
        ebi: float | None = None
        if self.target.ebd_based:
            ebi = self._emergency_intervention_m(v, acceleration_mps2)
            sbi = ebi + v * t.t_bs2_s
        else:
            sbi = self.curve.distance_m(v) + v * t.t_bs1_s
        permitted = sbi + v * t.t_driver_s
        return LimitDistances(
            emergency_brake_intervention_m=ebi,
            service_brake_intervention_m=sbi,
            warning_m=sbi + v * t.t_warning_s,
            permitted_m=permitted,
            indication_m=permitted + v * t.t_indication_s,
        )

    def distance_m(
        self, limit: Limit, speed_mps: float, *, acceleration_mps2: float = 0.0
    ) -> float:
        """Distance [m] before the target at which ``limit`` lies for that speed [m/s]."""
        self._check_limit(limit)
        _check_speed(speed_mps, acceleration_mps2)
        return self._limit_m(limit, speed_mps, acceleration_mps2)

    def location_m(
        self, limit: Limit, speed_mps: float, *, acceleration_mps2: float = 0.0
    ) -> float:
        """Track location [m] of ``limit`` for that speed [m/s]."""
        return self.target.location_m - self.distance_m(
            limit, speed_mps, acceleration_mps2=acceleration_mps2
        )

    def speed_mps(
        self, limit: Limit, distance_m: float, *, acceleration_mps2: float = 0.0
    ) -> float:
        """The limit's speed [m/s] at ``distance_m`` [m] before the target.

        The highest speed whose limit lies at that distance or further on (within
        :data:`SPEED_TOLERANCE_MPS`); 0 if even standstill's limit lies further back.
        """
        self._check_limit(limit)
        if not (math.isfinite(distance_m) and math.isfinite(acceleration_mps2)):
            raise EtcsInputError(f"distance {distance_m} m and acceleration must be finite")
        if limit is Limit.EBD or limit is Limit.SBD:
            return self.curve.speed_mps(distance_m)
        return _limit_speed(distance_m, *self._compiled(limit, acceleration_mps2))

    def _compiled(
        self, limit: Limit, acceleration_mps2: float
    ) -> tuple[int, CurveArrays, tuple[float, float, float, float], _Emergency]:
        """:func:`_limit_distance`'s arguments after the speed: the limit's code, the curve,
        the times (T_bs1 or T_bs2, warning, driver, indication) and what the emergency
        intervention's distance needs besides the speed (``_emergency_intervention_m`` with
        what does not depend on the speed worked out once)."""
        t = self.times
        a_est1 = 0.0 if acceleration_mps2 < 0.0 else acceleration_mps2
        a_est2 = self._a_est2_max if self._a_est2_max < a_est1 else a_est1
        v_delta1 = a_est1 * t.t_traction_s
        v_delta2 = a_est2 * t.t_berem_s
        emergency = (
            self.target.ebd_based,
            self._accuracy_compensated,
            self.target.speed_mps,
            (v_delta1, v_delta2, v_delta1 / 2.0, v_delta2 / 2.0),
            (t.t_traction_s, t.t_berem_s),
        )
        service_s = t.t_bs2_s if self.target.ebd_based else t.t_bs1_s
        times = (service_s, t.t_warning_s, t.t_driver_s, t.t_indication_s)
        return _LIMIT_CODES[limit], self.curve.arrays(), times, emergency

    def _check_limit(self, limit: Limit) -> None:
        if limit not in self.limits:
            raise EtcsInputError(f"a {self.target.kind.value} target has no {limit.value} limit")


def _check_speed(speed_mps: float, acceleration_mps2: float) -> None:
    if not (math.isfinite(speed_mps) and speed_mps >= 0.0 and math.isfinite(acceleration_mps2)):
        raise EtcsInputError(
            f"speed {speed_mps} m/s must be finite and ≥ 0, acceleration {acceleration_mps2} finite"
        )


class BrakingModel:
    """The train's braking as ETCS sees it: decelerations, times and the limits of targets.

    Parameters
    ----------
    train : TrainData
        The vehicle; the URV's by default.
    national, fixed : NationalValues, FixedValues
        The values in force; the A.3 defaults by default.
    """

    def __init__(
        self,
        train: TrainData = URV_TRAIN_DATA,
        *,
        national: NationalValues = NATIONAL_DEFAULTS,
        fixed: FixedValues = FIXED_VALUES,
    ) -> None:
        self.train = train
        self.national = national
        self.fixed = fixed
        self.a_brake_safe_mps2 = brake_safe_deceleration_mps2(train, national)
        """A_brake_safe [m/s²], before the gradient."""
        self.a_brake_service_mps2 = train.a_brake_service_mps2
        """A_brake_service [m/s²], before the gradient (A_expected's brake part)."""

    def times(self, target_speed_mps: float = 0.0) -> BrakingTimes:
        """The limit times [s] for a target of that speed [m/s]."""
        return braking_times(
            self.train, national=self.national, fixed=self.fixed, target_speed_mps=target_speed_mps
        )

    def deceleration_profile(
        self,
        kind: TargetKind,
        *,
        track_map: TrackMap | None = None,
        start_m: float = 0.0,
        end_m: float = 1.0,
    ) -> DecelerationProfile:
        """A_safe (EBD-based kinds) or A_expected (EoA) over ``[start_m, end_m)`` [m].

        Without a track map the track is level.
        """
        brake = self.a_brake_service_mps2
        if kind is not TargetKind.END_OF_AUTHORITY:
            brake = self.a_brake_safe_mps2
        if track_map is None:
            return DecelerationProfile.uniform(brake)
        return DecelerationProfile.from_track_map(
            track_map,
            start_m=start_m,
            end_m=end_m,
            brake_deceleration_mps2=brake,
            train_length_m=self.train.length_m,
            fixed=self.fixed,
            rotating_mass_percent=self.train.rotating_mass_percent,
        )

    def target_limits(
        self, target: Target, *, track_map: TrackMap | None = None, from_m: float | None = None
    ) -> TargetLimits:
        """The curve and limits of ``target``, with the gradient from ``from_m`` [m] on.

        ``from_m`` defaults to :data:`DEFAULT_LOOKBACK_M` before the target; before it the
        deceleration found there holds.
        """
        if not (math.isfinite(target.location_m) and math.isfinite(target.speed_mps)):
            raise EtcsInputError(f"target {target} is not finite")
        start_m = target.location_m - DEFAULT_LOOKBACK_M if from_m is None else from_m
        end_m = target.location_m + 1.0
        if not start_m < end_m:
            raise EtcsInputError(f"window start {start_m} m is not before the target")
        profile = self.deceleration_profile(
            target.kind, track_map=track_map, start_m=start_m, end_m=end_m
        )
        speed_at_target = 0.0
        if target.kind is TargetKind.SPEED_DECREASE:
            speed_at_target = target.speed_mps + dv_ebi_mps(target.speed_mps, self.fixed)
        curve = BrakingCurve(profile, target_m=target.location_m, target_speed_mps=speed_at_target)
        return TargetLimits(
            target,
            curve,
            self.times(target.speed_mps),
            fixed=self.fixed,
            national=self.national,
        )


# -- the bisection, compiled -------------------------------------------------------------------

CurveArrays = tuple[FloatArray, FloatArray, FloatArray, float]
"""A braking curve's squares, bands and decelerations, and twice the deceleration beyond its
target (:meth:`BrakingCurve.arrays`)."""
_Emergency = tuple[bool, bool, float, tuple[float, float, float, float], tuple[float, float]]
"""EBD-based, V_ura compensated, V_target, (V_delta1, V_delta2, their halves), (T_traction,
T_berem)."""

_EBI, _SBI, _WARNING, _PERMITTED, _INDICATION = range(5)
_LIMIT_CODES = {
    Limit.EBI: _EBI,
    Limit.SBI1: _SBI,
    Limit.SBI2: _SBI,
    Limit.WARNING: _WARNING,
    Limit.PERMITTED: _PERMITTED,
    Limit.INDICATION: _INDICATION,
}
_jit = compiled(units)
"""The supervision's bisection compiled; V_ura's constants come from ``protocol.units``."""


@_jit
def _curve_distance(v: float, curve: CurveArrays) -> float:
    """:meth:`BrakingCurve.distance_m`, the same arithmetic, operation for operation."""
    squares, bands, decelerations, beyond_twice = curve
    square = v * v
    first_square: float = squares[0]
    if square < first_square:
        return -(first_square - square) / beyond_twice
    k = np.searchsorted(squares, square, side="right") - 1
    distance: float = bands[k] + (square - squares[k]) / (2.0 * decelerations[k])
    return distance


@_jit
def _limit_distance(
    v: float,
    code: int,
    curve: CurveArrays,
    times: tuple[float, float, float, float],
    emergency: _Emergency,
) -> float:
    """``TargetLimits._limit_m`` for the limit of that code at speed ``v`` (a test checks the
    bits): V_ura's pieces and the built-ins' ``max`` written out as they choose."""
    ebd_based, compensated, v_target, deltas, emergency_times = emergency
    v_delta1, v_delta2, half_delta1, half_delta2 = deltas
    t_traction, t_berem = emergency_times
    t_service, t_warning, t_driver, t_indication = times
    if ebd_based:
        if not compensated:
            v_delta0 = 0.0
        elif v <= _URA_FROM_MPS:
            v_delta0 = _URA_MIN_MPS
        else:
            ura = _URA_MIN_MPS + _URA_SLOPE * (v - _URA_FROM_MPS)
            v_delta0 = _URA_MAX_MPS if ura > _URA_MAX_MPS else ura
        fastest = v + v_delta0 + v_delta1
        fastest = v_target if v_target > fastest else fastest
        traction = v + v_delta0 + half_delta1
        traction = v_target if v_target > traction else traction
        d_bec = traction * t_traction + (fastest + half_delta2) * t_berem
        distance = _curve_distance(fastest + v_delta2, curve) + d_bec
        if code == _EBI:
            return distance
    else:
        distance = _curve_distance(v, curve)
    distance = distance + v * t_service
    if code == _SBI:
        return distance
    if code == _WARNING:
        return distance + v * t_warning
    distance = distance + v * t_driver
    if code == _PERMITTED:
        return distance
    return distance + v * t_indication


@_jit
def _limit_speed(
    distance_m: float,
    code: int,
    curve: CurveArrays,
    times: tuple[float, float, float, float],
    emergency: _Emergency,
) -> float:
    """The highest speed whose limit lies at ``distance_m`` or further on, within
    :data:`SPEED_TOLERANCE_MPS` (:meth:`TargetLimits.speed_mps`); 0 if even standstill's lies
    further back. Every limit's distance grows with the speed: bisect for the crossing."""
    if _limit_distance(0.0, code, curve, times, emergency) > distance_m:
        return 0.0
    low, high = 0.0, _SPEED_SEARCH_MPS
    while _limit_distance(high, code, curve, times, emergency) <= distance_m:
        low, high = high, 2.0 * high
        if high > _SPEED_SEARCH_MAX_MPS:
            return low
    while high - low > SPEED_TOLERANCE_MPS:
        middle = 0.5 * (low + high)
        if _limit_distance(middle, code, curve, times, emergency) > distance_m:
            high = middle
        else:
            low = middle
    return low
