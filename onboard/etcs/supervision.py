"""Speed and distance monitoring (SUBSET-026 §3.13.10; DOMAIN.md §1.3): statuses and commands.

Three monitorings run side by side; the status is the most severe of their outcomes and the
permitted speed the lowest:

- **CSM**, ceiling speed (Table 5): V > MRSP → Overspeed; V > MRSP + dV_warning → Warning;
  V > MRSP + dV_sbi → SB and Intervention; V > MRSP + dV_ebi → EB and Intervention.
- **TSM**, target speed, for each target the train runs faster than: with the relevant front
  end (estimated for the EoA, max-safe for the SvL and MRSP targets) beyond I → Indication,
  beyond P → Overspeed, beyond W → Warning, beyond SBI → SB and Intervention, beyond EBI →
  EB and Intervention. The permitted speed of a target is its P speed there, at least the
  target speed.
- **RSM**, release speed: once the estimated front end passes SBI1(EoA) or the max-safe front
  end passes SBI2(SvL), both taken at V_release, the EoA and SvL are supervised against the
  release speed alone, which is an EBI: V > V_release → EB and Intervention.

Where no service brake is fitted, and in TSM where Q_NVSBTSMPERM forbids it, the EB replaces
the SB. :class:`InterventionLatch` holds the commands between cycles:

- EB until standstill (Q_NVEMRRLS default), or until its cause has gone otherwise;
- SB until V ≤ the permitted speed (status back to Normal or Indication);
- traction cut-off from Warning on and with any brake command, revoked with them.

While a brake command is held the status stays Intervention.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from functools import cached_property
from typing import NamedTuple

from onboard.etcs.braking import (
    Limit,
    Target,
    TargetKind,
    TargetLimits,
    dv_ebi_mps,
    dv_sbi_mps,
    dv_warning_mps,
)
from onboard.etcs.odometry import ConfidenceInterval
from onboard.etcs.values import FIXED_VALUES, FixedValues
from protocol.messages import SupervisionStatus

__all__ = [
    "BrakeCommands",
    "Demand",
    "InterventionLatch",
    "Monitoring",
    "ReleaseSpeedArea",
    "SupervisionResult",
    "ceiling_speed_monitoring",
    "release_speed_area",
    "release_speed_monitoring",
    "severity",
    "supervise",
    "target_speed_monitoring",
]


class Monitoring(StrEnum):
    """The monitoring in charge: ceiling, target or release speed."""

    CEILING_SPEED = "csm"
    TARGET_SPEED = "tsm"
    RELEASE_SPEED = "rsm"


_SEVERITY = {
    SupervisionStatus.NORMAL: 0,
    SupervisionStatus.INDICATION: 1,
    SupervisionStatus.OVERSPEED: 2,
    SupervisionStatus.WARNING: 3,
    SupervisionStatus.INTERVENTION: 4,
}


def severity(status: SupervisionStatus) -> int:
    """0 for Normal up to 4 for Intervention."""
    return _SEVERITY[status]


@dataclass(frozen=True, kw_only=True)
class Demand:
    """What one monitoring asks for in one cycle, before the latch."""

    status: SupervisionStatus = SupervisionStatus.NORMAL
    service_brake: bool = False
    emergency_brake: bool = False

    def combined(self, other: Demand) -> Demand:
        """The more severe status, and both demands' brakes."""
        status = self.status if severity(self.status) >= severity(other.status) else other.status
        return Demand(
            status=status,
            service_brake=self.service_brake or other.service_brake,
            emergency_brake=self.emergency_brake or other.emergency_brake,
        )


_EMERGENCY = Demand(status=SupervisionStatus.INTERVENTION, emergency_brake=True)
_SERVICE = Demand(status=SupervisionStatus.INTERVENTION, service_brake=True)


def ceiling_speed_monitoring(
    speed_mps: float,
    ceiling_speed_mps: float,
    *,
    fixed: FixedValues = FIXED_VALUES,
    service_brake_available: bool = True,
) -> Demand:
    """CSM (Table 5) at the estimated speed [m/s] against the MRSP at the train [m/s]."""
    if speed_mps > ceiling_speed_mps + dv_ebi_mps(ceiling_speed_mps, fixed):
        return _EMERGENCY
    if speed_mps > ceiling_speed_mps + dv_sbi_mps(ceiling_speed_mps, fixed):
        return _SERVICE if service_brake_available else _EMERGENCY
    if speed_mps > ceiling_speed_mps + dv_warning_mps(ceiling_speed_mps, fixed):
        return Demand(status=SupervisionStatus.WARNING)
    if speed_mps > ceiling_speed_mps:
        return Demand(status=SupervisionStatus.OVERSPEED)
    return Demand()


def _front_m(target: Target, interval: ConfidenceInterval) -> float:
    return interval.max_safe_front_m if target.ebd_based else interval.estimated_front_m


def target_speed_monitoring(
    limits: TargetLimits,
    speed_mps: float,
    interval: ConfidenceInterval,
    *,
    acceleration_mps2: float = 0.0,
    service_brake_permitted: bool = True,
) -> Demand:
    """TSM of one target at the estimated speed [m/s] and acceleration [m/s²]."""
    target = limits.target
    if speed_mps <= target.speed_mps:
        return Demand()
    distance_m = target.location_m - _front_m(target, interval)
    d = limits.distances(speed_mps, acceleration_mps2=acceleration_mps2)
    ebi_m = d.emergency_brake_intervention_m
    if ebi_m is not None and distance_m < ebi_m:
        return _EMERGENCY
    if distance_m < d.service_brake_intervention_m:
        return _SERVICE if service_brake_permitted else _EMERGENCY
    if distance_m < d.warning_m:
        return Demand(status=SupervisionStatus.WARNING)
    if distance_m < d.permitted_m:
        return Demand(status=SupervisionStatus.OVERSPEED)
    if distance_m < d.indication_m:
        return Demand(status=SupervisionStatus.INDICATION)
    return Demand()


@dataclass(frozen=True, kw_only=True)
class ReleaseSpeedArea:
    """Where RSM takes over from the TSM of the EoA and SvL, and at what speed [m/s]."""

    speed_mps: float
    end_of_authority: Target
    supervised_location: Target
    end_of_authority_start_m: float
    """SBI1(EoA) at V_release [m]: compared with the estimated front end."""
    supervised_location_start_m: float
    """SBI2(SvL) at V_release [m]: compared with the max-safe front end."""

    def contains(self, interval: ConfidenceInterval) -> bool:
        """Whether the train is in the release-speed area."""
        return (
            interval.estimated_front_m > self.end_of_authority_start_m
            or interval.max_safe_front_m > self.supervised_location_start_m
        )


def release_speed_area(
    end_of_authority: TargetLimits, supervised_location: TargetLimits, release_speed_mps: float
) -> ReleaseSpeedArea:
    """The RSM area of an MA: from the more restrictive of SBI1(EoA) and SBI2(SvL)."""
    return ReleaseSpeedArea(
        speed_mps=release_speed_mps,
        end_of_authority=end_of_authority.target,
        supervised_location=supervised_location.target,
        end_of_authority_start_m=end_of_authority.location_m(Limit.SBI1, release_speed_mps),
        supervised_location_start_m=supervised_location.location_m(Limit.SBI2, release_speed_mps),
    )


def release_speed_monitoring(speed_mps: float, release_speed_mps: float) -> Demand:
    """RSM: the release speed is an EBI."""
    return _EMERGENCY if speed_mps > release_speed_mps else Demand()


@dataclass(frozen=True, kw_only=True)
class SupervisionResult:
    """The outcome of one cycle's monitoring, before the latch."""

    demand: Demand
    monitoring: Monitoring
    permitted_speed_mps: float
    ceiling_speed_mps: float
    target: Target | None
    """The most restrictive target: the one of the lowest permitted speed."""
    target_distance_m: float | None
    """From the relevant front end to that target [m]."""
    release_speed_mps: float | None
    ceiling_intervention_mps: float = math.inf
    """The ceiling's EBI speed, or the release speed in its area [m/s]."""
    intervention_targets: tuple[tuple[TargetLimits, float, float], ...] = ()
    """Each supervised target with its distance [m] and the acceleration [m/s²]: what
    :meth:`intervention_speed_mps` needs, kept so that it is computed only when asked for."""

    def intervention_speed_mps(self) -> float:
        """The speed at which supervision would intervene now [m/s]: the ceiling's EBI speed,
        each target's EBI (SBI1 for the EoA, which has no EBI) at the front end, the release
        speed (a status value: not used by the supervision itself)."""
        return self._intervention_speed_mps

    @cached_property
    def _intervention_speed_mps(self) -> float:
        # Worked out once per result: the status report and the operator both ask for it
        # between two supervision cycles, and each answer is a bisection per target.
        speed = self.ceiling_intervention_mps
        for limits, distance_m, acceleration_mps2 in self.intervention_targets:
            limit = Limit.EBI if Limit.EBI in limits.limits else Limit.SBI1
            speed = min(
                speed,
                max(
                    limits.target.speed_mps,
                    limits.speed_mps(limit, distance_m, acceleration_mps2=acceleration_mps2),
                ),
            )
        return speed


class _TargetsMonitored(NamedTuple):
    """What TSM of every target gives :func:`supervise`."""

    demand: Demand
    """The ceiling's demand combined with every target's."""
    permitted_mps: float
    """The lowest permitted speed [m/s], the ceiling's included."""
    intervention_targets: list[tuple[TargetLimits, float, float]]
    """Each target with its distance [m] and the acceleration [m/s²]."""
    shown: tuple[float, float, Target] | None
    """The most restrictive target: its permitted speed [m/s], its distance [m], itself."""
    in_target_speed: bool
    """Whether a target's TSM reached Indication or beyond."""


def _monitor_targets(
    targets: Sequence[TargetLimits],
    *,
    speed_mps: float,
    interval: ConfidenceInterval,
    demand: Demand,
    permitted_mps: float,
    in_release: bool,
    acceleration_mps2: float,
    service_brake_permitted: bool,
) -> _TargetsMonitored:
    """TSM of every target at the estimated speed [m/s] and acceleration [m/s²], on top of the
    ceiling's ``demand`` and permitted speed [m/s]; in the release-speed area only the MRSP's
    decreases (RSM supervises the EoA and the SvL)."""
    intervention_targets: list[tuple[TargetLimits, float, float]] = []
    shown: tuple[float, float, Target] | None = None
    in_target_speed = False
    for limits in targets:
        target = limits.target
        if in_release and target.kind is not TargetKind.SPEED_DECREASE:
            continue
        distance_m = target.location_m - _front_m(target, interval)
        target_permitted_mps = max(
            target.speed_mps,
            limits.speed_mps(Limit.PERMITTED, distance_m, acceleration_mps2=acceleration_mps2),
        )
        permitted_mps = min(permitted_mps, target_permitted_mps)
        intervention_targets.append((limits, distance_m, acceleration_mps2))
        if shown is None or target_permitted_mps < shown[0]:
            shown = (target_permitted_mps, distance_m, target)
        target_demand = target_speed_monitoring(
            limits,
            speed_mps,
            interval,
            acceleration_mps2=acceleration_mps2,
            service_brake_permitted=service_brake_permitted,
        )
        in_target_speed |= severity(target_demand.status) >= 1
        demand = demand.combined(target_demand)
    return _TargetsMonitored(demand, permitted_mps, intervention_targets, shown, in_target_speed)


def supervise(
    *,
    speed_mps: float,
    interval: ConfidenceInterval,
    ceiling_speed_mps: float,
    targets: Sequence[TargetLimits] = (),
    release: ReleaseSpeedArea | None = None,
    acceleration_mps2: float = 0.0,
    fixed: FixedValues = FIXED_VALUES,
    service_brake_available: bool = True,
    service_brake_in_target_speed_monitoring: bool = True,
) -> SupervisionResult:
    """Run CSM, TSM for every target, and RSM when the train is in the release-speed area."""
    demand = ceiling_speed_monitoring(
        speed_mps, ceiling_speed_mps, fixed=fixed, service_brake_available=service_brake_available
    )
    in_release = release is not None and release.contains(interval)
    intervention_mps = ceiling_speed_mps + dv_ebi_mps(ceiling_speed_mps, fixed)
    demand, permitted_mps, intervention_targets, shown, in_target_speed = _monitor_targets(
        targets,
        speed_mps=speed_mps,
        interval=interval,
        demand=demand,
        permitted_mps=ceiling_speed_mps,
        in_release=in_release,
        acceleration_mps2=acceleration_mps2,
        service_brake_permitted=(
            service_brake_available and service_brake_in_target_speed_monitoring
        ),
    )
    monitoring = Monitoring.TARGET_SPEED if in_target_speed else Monitoring.CEILING_SPEED
    if release is not None and in_release:
        monitoring = Monitoring.RELEASE_SPEED
        demand = demand.combined(release_speed_monitoring(speed_mps, release.speed_mps))
        permitted_mps = min(permitted_mps, release.speed_mps)
        intervention_mps = min(intervention_mps, release.speed_mps)
        eoa = release.end_of_authority
        if shown is None or release.speed_mps <= shown[0]:
            shown = (release.speed_mps, eoa.location_m - interval.estimated_front_m, eoa)
    return SupervisionResult(
        demand=demand,
        monitoring=monitoring,
        permitted_speed_mps=permitted_mps,
        ceiling_speed_mps=ceiling_speed_mps,
        target=None if shown is None else shown[2],
        target_distance_m=None if shown is None else shown[1],
        release_speed_mps=None if release is None else release.speed_mps,
        ceiling_intervention_mps=intervention_mps,
        intervention_targets=tuple(intervention_targets),
    )


@dataclass(frozen=True, kw_only=True)
class BrakeCommands:
    """The commands to the train: traction cut-off, service brake, emergency brake."""

    traction_cut: bool = False
    service_brake: bool = False
    emergency_brake: bool = False


class InterventionLatch:
    """Holds the commands between cycles and revokes them by SUBSET-026's rules.

    Parameters
    ----------
    release_at_standstill : bool
        Q_NVEMRRLS: the EB is revoked only at standstill (True) or once its cause has gone.
    """

    def __init__(self, *, release_at_standstill: bool = True) -> None:
        self.release_at_standstill = release_at_standstill
        self.commands = BrakeCommands()

    def update(
        self, demand: Demand, *, standstill: bool, forced_emergency_brake: bool = False
    ) -> BrakeCommands:
        """Latch this cycle's demand; ``forced_emergency_brake`` for TR and roll-away."""
        held = self.commands
        below_permitted = severity(demand.status) <= severity(SupervisionStatus.INDICATION)
        emergency = demand.emergency_brake or forced_emergency_brake
        if not emergency and held.emergency_brake:
            emergency = not standstill if self.release_at_standstill else False
        service = demand.service_brake or (held.service_brake and not below_permitted)
        traction_cut = (
            emergency
            or service
            or severity(demand.status) >= severity(SupervisionStatus.WARNING)
            or (held.traction_cut and not below_permitted)
        )
        self.commands = BrakeCommands(
            traction_cut=traction_cut, service_brake=service, emergency_brake=emergency
        )
        return self.commands

    def status(self, status: SupervisionStatus) -> SupervisionStatus:
        """The status to show: Intervention while a brake command is held."""
        if self.commands.service_brake or self.commands.emergency_brake:
            return SupervisionStatus.INTERVENTION
        return status

    def reset(self) -> None:
        """Drop every command (isolation)."""
        self.commands = BrakeCommands()
