"""What the ATO-OB controller is told each cycle, and the named conditions it checks on it.

The conditions follow DOMAIN.md §2.1 (SUBSET-125 §9), grouped as the controller uses them:

- **configuration** (CO → NA): the ETCS-OB link is up, the onboard track data has the
  trackside's version, no internal fault (seed 000: "checks its track database version equals
  the trackside one and runs internal tests", DOMAIN.md §7.1);
- **operational** (NA → AV; lost: AV/RE → NA, EG → DE): ETCS in AD, or in FS with "Entering FS"
  no longer displayed; no EB or full service brake from ETCS; no EB from others; End of Journey
  not reached; the journey profile valid and accepted, the track data consistent; the train
  localised within the journey profile and outside an ATO inhibition zone;
- **engagement** (AV → RE): the MA allows leaving, enough distance to the next stop, the dwell
  time elapsed, and (a GoA4 addition) the trackside session alive.

The cab conditions of SUBSET-125 (direction controller in forward, doors closed and locked, train
brake lever not in brake) have no counterpart on the unmanned inspection vehicle: there is no cab,
no passenger door, and the direction is the journey profile's (docs/ato_ob.md).

Every failed condition has a stable name (:class:`Condition`), reported in the status report and
on the console as the reason the ATO is not available or not ready.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING

from onboard.ato_ob._exceptions import AtoObInputError
from protocol.messages import EtcsMode

if TYPE_CHECKING:
    from onboard.etcs import EtcsOutput

__all__ = [
    "CONFIGURATION_CONDITIONS",
    "ENGAGEMENT_CONDITIONS",
    "OPERATIONAL_CONDITIONS",
    "AtoObInputs",
    "Condition",
    "EtcsStatus",
    "failed_configuration_conditions",
    "failed_engagement_conditions",
    "failed_operational_conditions",
]


class Condition(StrEnum):
    """A condition the controller checks; its value names it in reports when it fails."""

    ETCS_LINK = "etcs_link"
    """An ETCS-OB output received within the link timeout."""
    NO_INTERNAL_FAULT = "no_internal_fault"
    TRACK_DATA_VERSION = "track_data_version"
    """The onboard track data has the trackside's version (the data is consistent)."""
    ETCS_MODE = "etcs_mode"
    """ETCS in AD, or in FS with "Entering FS" no longer displayed; only AD once engaged."""
    NO_ETCS_BRAKE = "no_etcs_brake"
    """ETCS commands neither the EB nor the service brake."""
    NO_OTHER_EMERGENCY_BRAKE = "no_other_emergency_brake"
    END_OF_JOURNEY_NOT_REACHED = "end_of_journey_not_reached"
    JOURNEY_PROFILE_VALID = "journey_profile_valid"
    JOURNEY_PROFILE_ACCEPTED = "journey_profile_accepted"
    LOCALISED = "localised"
    """The localisation is valid and the train within the journey profile."""
    OUTSIDE_INHIBITION_ZONE = "outside_inhibition_zone"
    MOVEMENT_AUTHORITY = "movement_authority"
    """The MA allows leaving the platform."""
    DISTANCE_TO_NEXT_STOP = "distance_to_next_stop"
    DWELL_TIME_ELAPSED = "dwell_time_elapsed"
    TRACKSIDE_SESSION = "trackside_session"


CONFIGURATION_CONDITIONS: tuple[Condition, ...] = (
    Condition.ETCS_LINK,
    Condition.TRACK_DATA_VERSION,
    Condition.NO_INTERNAL_FAULT,
)
OPERATIONAL_CONDITIONS: tuple[Condition, ...] = (
    Condition.ETCS_MODE,
    Condition.NO_ETCS_BRAKE,
    Condition.NO_OTHER_EMERGENCY_BRAKE,
    Condition.END_OF_JOURNEY_NOT_REACHED,
    Condition.JOURNEY_PROFILE_VALID,
    Condition.JOURNEY_PROFILE_ACCEPTED,
    Condition.TRACK_DATA_VERSION,
    Condition.LOCALISED,
    Condition.OUTSIDE_INHIBITION_ZONE,
)
ENGAGEMENT_CONDITIONS: tuple[Condition, ...] = (
    Condition.MOVEMENT_AUTHORITY,
    Condition.DISTANCE_TO_NEXT_STOP,
    Condition.DWELL_TIME_ELAPSED,
    Condition.TRACKSIDE_SESSION,
)


@dataclass(frozen=True, kw_only=True)
class EtcsStatus:
    """What the ATO-OB reads from one ETCS-OB output (the ETCS side of SUBSET-130).

    ``received_s`` is when the ATO-OB received it: the link is supervised on it. The limits are
    passed through to the ADF unchanged.
    """

    mode: EtcsMode
    service_brake: bool
    emergency_brake: bool
    traction_cut: bool = False
    permitted_speed_mps: float
    """The speed not to exceed now [m/s]."""
    end_of_authority_distance_m: float | None
    """From the estimated front end to the EoA [m]; None without an MA."""
    supervised_location_distance_m: float | None = None
    """From the max-safe front end to the SvL [m]; None without an MA."""
    entering_full_supervision_displayed: bool = False
    """The DMI still shows "Entering FS": the ATO must wait (DOMAIN.md §2.1)."""
    received_s: float
    """When the ATO-OB received this output [s]."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.permitted_speed_mps) and self.permitted_speed_mps >= 0.0):
            raise AtoObInputError("the permitted speed must be finite and not negative")
        if not math.isfinite(self.received_s):
            raise AtoObInputError("the reception time must be finite")
        for distance in (self.end_of_authority_distance_m, self.supervised_location_distance_m):
            if distance is not None and not math.isfinite(distance):
                raise AtoObInputError("the EoA and SvL distances must be finite")

    @classmethod
    def from_output(cls, output: EtcsOutput, *, received_s: float | None = None) -> EtcsStatus:
        """The status of an :class:`onboard.etcs.EtcsOutput`, received at its time by default."""
        return cls(
            mode=output.mode,
            service_brake=output.service_brake,
            emergency_brake=output.emergency_brake,
            traction_cut=output.traction_cut,
            permitted_speed_mps=output.permitted_speed_mps,
            end_of_authority_distance_m=output.end_of_authority_distance_m,
            supervised_location_distance_m=output.supervised_location_distance_m,
            received_s=output.time_s if received_s is None else received_s,
        )


@dataclass(frozen=True, kw_only=True)
class AtoObInputs:
    """One cycle's inputs of :meth:`onboard.ato_ob.AtoObController.step`.

    The booleans are facts established by the other onboard parts: the track database manager
    (journey profile, track data, localisation, stopping points), the ADF (dwell, distance to the
    next stop), the session layer (trackside session) and the vehicle (standstill).
    """

    etcs: EtcsStatus | None
    """The latest ETCS-OB output, or None when nothing new came (the last one is kept)."""
    journey_profile_valid: bool
    """The track database manager validated the journey profile against the track data."""
    journey_profile_accepted: bool
    """The journey profile was acknowledged to the ATO-TS (JPAck) and is the one in force."""
    track_data_version_matches: bool
    localisation_valid: bool
    """The train is localised on the track map, within the journey profile."""
    end_of_journey_reached: bool
    standstill: bool
    at_stopping_point: bool
    """The front end is within the Stopping Point Reached distance of a stopping point."""
    dwell_elapsed: bool
    """The minimum dwell time at this stop has elapsed (true away from a stop)."""
    movement_authority_allows_departure: bool
    distance_to_next_stop_sufficient: bool
    trackside_session_alive: bool
    remote_driving_selected: bool = False
    """The remote driver drives (the ADF's RD controller) while the ATO is not engaged."""
    other_emergency_brake: bool = False
    """An EB from another source than ETCS, e.g. the VC."""
    in_inhibition_zone: bool = False
    """The train is in an ATO Inhibition Zone of the journey profile's Temporary Constraints."""
    internal_fault: bool = False
    """A fault of the ATO-OB itself (a watchdog, the ADF, a failed self-test)."""


def failed_configuration_conditions(
    inputs: AtoObInputs, *, etcs_link_alive: bool
) -> tuple[Condition, ...]:
    """The configuration conditions that fail, in :data:`CONFIGURATION_CONDITIONS` order."""
    holds = {
        Condition.ETCS_LINK: etcs_link_alive,
        Condition.TRACK_DATA_VERSION: inputs.track_data_version_matches,
        Condition.NO_INTERNAL_FAULT: not inputs.internal_fault,
    }
    return tuple(condition for condition in CONFIGURATION_CONDITIONS if not holds[condition])


def failed_operational_conditions(
    inputs: AtoObInputs,
    etcs: EtcsStatus | None,
    *,
    automatic_driving_required: bool = False,
    end_of_journey_pending: bool = False,
) -> tuple[Condition, ...]:
    """The operational conditions that fail, in :data:`OPERATIONAL_CONDITIONS` order.

    Parameters
    ----------
    inputs : AtoObInputs
        This cycle's inputs.
    etcs : EtcsStatus or None
        The latest ETCS-OB status; None fails the ETCS conditions.
    automatic_driving_required : bool
        Only AD satisfies the ETCS mode (engaged, once ETCS has had time to enter AD).
    end_of_journey_pending : bool
        Do not count the End of Journey as reached: the train, engaged and moving, is
        stopping at it.
    """
    if etcs is None:
        mode_ok = braking_ok = False
    else:
        in_full_supervision = (
            etcs.mode is EtcsMode.FS and not etcs.entering_full_supervision_displayed
        )
        mode_ok = etcs.mode is EtcsMode.AD or (
            in_full_supervision and not automatic_driving_required
        )
        braking_ok = not (etcs.service_brake or etcs.emergency_brake)
    holds = {
        Condition.ETCS_MODE: mode_ok,
        Condition.NO_ETCS_BRAKE: braking_ok,
        Condition.NO_OTHER_EMERGENCY_BRAKE: not inputs.other_emergency_brake,
        Condition.END_OF_JOURNEY_NOT_REACHED: (
            not inputs.end_of_journey_reached or end_of_journey_pending
        ),
        Condition.JOURNEY_PROFILE_VALID: inputs.journey_profile_valid,
        Condition.JOURNEY_PROFILE_ACCEPTED: inputs.journey_profile_accepted,
        Condition.TRACK_DATA_VERSION: inputs.track_data_version_matches,
        Condition.LOCALISED: inputs.localisation_valid,
        Condition.OUTSIDE_INHIBITION_ZONE: not inputs.in_inhibition_zone,
    }
    return tuple(condition for condition in OPERATIONAL_CONDITIONS if not holds[condition])


def failed_engagement_conditions(inputs: AtoObInputs) -> tuple[Condition, ...]:
    """The engagement conditions that fail, in :data:`ENGAGEMENT_CONDITIONS` order."""
    holds = {
        Condition.MOVEMENT_AUTHORITY: inputs.movement_authority_allows_departure,
        Condition.DISTANCE_TO_NEXT_STOP: inputs.distance_to_next_stop_sufficient,
        Condition.DWELL_TIME_ELAPSED: inputs.dwell_elapsed,
        Condition.TRACKSIDE_SESSION: inputs.trackside_session_alive,
    }
    return tuple(condition for condition in ENGAGEMENT_CONDITIONS if not holds[condition])
