"""One cycle's speed and distance supervision of a running train, for :class:`EtcsOnboard`.

The MRSP is min(the TrackMap's MRSP with its TSRs, the train's maximum speed, the mode's limit):

- CSM's ceiling is its lowest value under the train, from the min-safe rear end to the max-safe
  front end;
- each decrease ahead of the max-safe front end, up to the SvL or the lookahead, is a target;
- with an MA, the EoA and the SvL are targets too, and RSM takes over near them.

The lookahead is how far a decrease can matter: the I limit of the fastest the train may run on
the line, braking on the line's steepest downhill. A target's limits are built once (its curve
reads the TrackMap's gradients) and kept while the target stays. The release speed is the MA's,
or calculated on board: the speed whose EBI for the SvL lies at the EoA, so that the EB stops the
train before the SvL from there.
"""

from __future__ import annotations

import math

from onboard.etcs.braking import BrakingModel, Limit, Target, TargetKind, TargetLimits, dv_ebi_mps
from onboard.etcs.deceleration import gradient_acceleration_mps2
from onboard.etcs.odometry import ConfidenceInterval
from onboard.etcs.supervision import ReleaseSpeedArea, SupervisionResult, release_speed_area
from onboard.etcs.supervision import supervise as run_supervision
from trackdb import TrackMap

__all__ = ["MotionSupervisor"]

_LOCATION_DIGITS = 6
"""Decimals [m] a decrease's location is rounded to, so that its target stays the same."""


class MotionSupervisor:
    """Builds a cycle's targets from the line and the MA, and supervises against them."""

    def __init__(self, track_map: TrackMap, braking: BrakingModel) -> None:
        self.track_map = track_map
        self.braking = braking
        self.lookahead_m = self._lookahead_m()
        self._limits: dict[Target, TargetLimits] = {}
        self._release: tuple[tuple[float, float], float] | None = None

    def use_line(self, track_map: TrackMap) -> None:
        """New track data: the look-ahead and every target's curves are computed again."""
        self.track_map = track_map
        self.lookahead_m = self._lookahead_m()
        self._limits.clear()
        self._release = None

    def _lookahead_m(self) -> float:
        line, train, braking = self.track_map.line, self.braking.train, self.braking
        speed_mps = min(max(s.value for s in line.speed_limit_mps), train.max_speed_mps)
        speed_mps += dv_ebi_mps(speed_mps, braking.fixed)
        steepest = min(0.0, *(s.value for s in line.gradient_permille))
        deceleration = min(braking.a_brake_safe_mps2, braking.a_brake_service_mps2)
        deceleration += gradient_acceleration_mps2(steepest, fixed=braking.fixed)
        t = braking.times()
        reaction_s = t.t_traction_s + t.t_berem_s + t.t_bs_s + t.t_driver_s + t.t_indication_s
        braking_m = speed_mps**2 / (2.0 * max(deceleration, 0.05))
        return 1.1 * (braking_m + speed_mps * (reaction_s + 2.0)) + train.length_m + 100.0

    def ceiling_mps(self, interval: ConfidenceInterval, limit_mps: float) -> float:
        """The lowest MRSP [m/s] under the train, and the mode's limit."""
        rear_m = interval.min_safe_front_m - self.braking.train.length_m
        sections = self.track_map.mrsp_window(rear_m, interval.max_safe_front_m - rear_m)
        lowest = min(
            (section.speed_mps for section in sections),
            default=self.track_map.mrsp_mps(interval.estimated_front_m),
        )
        return min(lowest, limit_mps)

    def speed_decreases(
        self, interval: ConfidenceInterval, limit_mps: float, end_m: float
    ) -> list[Target]:
        """The MRSP's decreases from the max-safe front end to ``end_m`` [m]."""
        start_m = interval.max_safe_front_m
        if end_m <= start_m:
            return []
        targets: list[Target] = []
        previous_mps = math.inf
        for index, section in enumerate(self.track_map.mrsp_window(start_m, end_m - start_m)):
            speed_mps = min(section.speed_mps, limit_mps)
            if index and speed_mps < previous_mps:
                location_m = round(start_m + section.from_distance_m, _LOCATION_DIGITS)
                targets.append(Target(TargetKind.SPEED_DECREASE, location_m, speed_mps))
            previous_mps = speed_mps
        return targets

    def supervise(
        self,
        *,
        interval: ConfidenceInterval,
        speed_mps: float,
        acceleration_mps2: float,
        limit_mps: float,
        authority_m: tuple[float, float] | None,
        release_speed_mps: float | None,
    ) -> SupervisionResult:
        """Supervise with the mode's speed limit [m/s] and, if given, the (EoA, SvL) [m].

        ``release_speed_mps`` is the MA's release speed; None calculates it on board.
        """
        used: dict[Target, TargetLimits] = {}

        def limits_of(target: Target) -> TargetLimits:
            limits = self._limits.get(target)
            if limits is None:
                from_m = interval.min_safe_front_m - self.braking.train.length_m - 1.0
                limits = self.braking.target_limits(target, track_map=self.track_map, from_m=from_m)
            used[target] = limits
            return limits

        end_m = interval.max_safe_front_m + self.lookahead_m
        targets: list[TargetLimits] = []
        release: ReleaseSpeedArea | None = None
        if authority_m is not None:
            eoa_m, svl_m = authority_m
            end_m = min(end_m, svl_m)
            eoa = limits_of(Target(TargetKind.END_OF_AUTHORITY, eoa_m))
            svl = limits_of(Target(TargetKind.SUPERVISED_LOCATION, svl_m))
            targets += [eoa, svl]
            if release_speed_mps is None:
                release_speed_mps = self._calculated_release_speed_mps(eoa_m, svl)
            if release_speed_mps > 0.0:
                release = release_speed_area(eoa, svl, release_speed_mps)
        targets += [limits_of(t) for t in self.speed_decreases(interval, limit_mps, end_m)]
        self._limits = used
        national, train = self.braking.national, self.braking.train
        return run_supervision(
            speed_mps=speed_mps,
            interval=interval,
            ceiling_speed_mps=self.ceiling_mps(interval, limit_mps),
            targets=targets,
            release=release,
            acceleration_mps2=acceleration_mps2,
            fixed=self.braking.fixed,
            service_brake_available=train.service_brake_available,
            service_brake_in_target_speed_monitoring=(
                national.service_brake_in_target_speed_monitoring
            ),
        )

    def _calculated_release_speed_mps(self, eoa_m: float, svl: TargetLimits) -> float:
        key = (eoa_m, svl.target.location_m)
        if self._release is None or self._release[0] != key:
            speed_mps = svl.speed_mps(Limit.EBI, svl.target.location_m - eoa_m)
            self._release = (key, speed_mps)
        return self._release[1]
