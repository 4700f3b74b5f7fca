"""What :class:`EtcsOnboard` does with a balise group read, and with a linked group missed.

:class:`BaliseIntake` reads a group (:func:`read_balise_group`) found where the odometer was
then, relocates the odometry on it with its Q_LOCACC (the linking packet's, else Q_NVLOCACC,
plus the reader's location error) and makes it the LRBG (:class:`Localisation`), and delivers
its packets: the reach of the SSP and gradient, a level transition, the Level 1 MA. It checks
the linked groups' expectation windows (:mod:`onboard.etcs.linking`) and takes the linking
reaction of a group missed or read outside its window: a trip, or the service brake held to
standstill, in FS, OS and AD. A group read in IS is only recorded; in TR it relocates the
odometry but delivers no packet.
"""

from __future__ import annotations

from collections.abc import Sequence

from onboard.etcs.authority import AuthorityKeeper
from onboard.etcs.balises import (
    BaliseGroupReading,
    LinkedGroup,
    balise_groups_passed,
    read_balise_group,
)
from onboard.etcs.linking import LinkingEvent, LinkingFault
from onboard.etcs.localisation import Localisation, OdometerPoint
from onboard.etcs.mode_control import ModeControl
from onboard.etcs.mode_supervision import ModeSupervision
from onboard.etcs.modes import SUPERVISED_MODES, ModeCondition
from onboard.etcs.movement_authority import EtcsLevel
from onboard.etcs.odometer import Odometer
from onboard.etcs.supervision import Monitoring
from onboard.etcs.values import NationalValues
from onboard.plant.readings import BaliseDetection
from protocol.messages import EtcsMode
from trackdb import BaliseGroup
from trackdb.schema import LinkReaction

__all__ = ["BaliseIntake"]


class BaliseIntake:
    """Balise groups read, their packets delivered, the linking faults and their reactions.

    Parameters
    ----------
    where : Localisation
        The odometry to relocate and the linked groups' windows.
    authority : AuthorityKeeper
        Where a group's MA and track description go.
    modes : ModeControl
        The mode and level, where a level transition and a trip condition go.
    supervision : ModeSupervision
        The last result (RSM) and the linking reaction's service brake.
    national : NationalValues
        Q_NVLOCACC.
    """

    def __init__(
        self,
        where: Localisation,
        authority: AuthorityKeeper,
        modes: ModeControl,
        supervision: ModeSupervision,
        national: NationalValues,
    ) -> None:
        self.linking_events: list[LinkingEvent] = []
        """Every linking fault so far."""
        self.last_reading: BaliseGroupReading | None = None
        self._where = where
        self._authority = authority
        self._modes = modes
        self._supervision = supervision
        self._national = national
        self._unreported: list[LinkingEvent] = []
        self._readings = 0

    def read(
        self,
        group: BaliseGroup,
        now_s: float,
        *,
        time_s: float,
        at: OdometerPoint,
        reader_error_m: float = 0.0,
    ) -> BaliseGroupReading:
        """Read ``group`` found at ``time_s`` [s], when the odometer was ``at``; the reader's
        location error [m] adds to the group's accuracy."""
        location_m = self._where.locate(group.position_m)
        link = self._where.linking.announcement(group.id)
        reading = read_balise_group(
            group,
            location_m=location_m,
            time_s=time_s,
            linked=link is not None,
            message_counter=self._readings,
        )
        self._readings += 1
        self.last_reading = reading
        if self._modes.mode is EtcsMode.IS:
            return reading
        accuracy_m = self._national.q_nvlocacc_m if link is None else link.location_accuracy_m
        faults = self._where.relocate(
            group.id,
            location_m,
            at=at,
            location_accuracy_m=accuracy_m + reader_error_m,
            linked_groups=reading.linked_groups,
        )
        for linked, fault in faults:
            self._linking_fault(linked, fault, now_s)
        if self._modes.mode is EtcsMode.TR:
            return reading
        self._deliver(reading, location_m, now_s)
        return reading

    def read_passed(self, from_m: float, now_s: float) -> None:
        """Read from the TrackMap the groups the front end passed since the odometer was at
        ``from_m`` [m] (the given-motion path), each where it lies."""
        passed = balise_groups_passed(self._where.track_map, from_m, self._where.odometer_m)
        for group, odometer_m in passed:
            self.read(group, now_s, time_s=now_s, at=OdometerPoint(odometer_m=odometer_m))

    def read_detected(
        self, odometer: Odometer, detections: Sequence[BaliseDetection], now_s: float
    ) -> None:
        """Read the groups the reader located (the sensor path), in time order: each where the
        odometer was at its detection, with the reader's location error."""
        for detection in detections:
            self.read(
                detection.group,
                now_s,
                time_s=detection.time_s,
                at=self._where.detection_position(odometer, detection.time_s),
                reader_error_m=odometer.parameters.balise_location_error_m,
            )

    def _deliver(self, reading: BaliseGroupReading, location_m: float, now_s: float) -> None:
        """The packets of a group read at ``location_m`` [m], outside IS and TR."""
        authority, modes = self._authority, self._modes
        if reading.static_speed_profile_end_m is not None:
            end_m = reading.static_speed_profile_end_m
            authority.track_description.receive_static_speed_profile(location_m, end_m)
        if reading.gradient_end_m is not None:
            authority.track_description.receive_gradient(location_m, reading.gradient_end_m)
        if reading.level_transition is not None:
            modes.level_transitions.append(reading.level_transition)
        if reading.movement_authority is not None and modes.level is EtcsLevel.LEVEL_1:
            authority.accept(reading.movement_authority, now_s, reference_location_m=location_m)
        if (
            modes.mode in SUPERVISED_MODES
            and authority.in_force is not None
            and self._supervision.result.monitoring is Monitoring.RELEASE_SPEED
            and location_m >= authority.locations()[0]
        ):
            modes.events.add(ModeCondition.BALISE_GROUP_AT_END_OF_AUTHORITY)

    def check_windows(self, now_s: float) -> None:
        """The linked groups whose window the min-safe front end has passed unread."""
        for group, fault in self._where.missed_groups():
            self._linking_fault(group, fault, now_s)

    def _linking_fault(self, group: LinkedGroup, fault: LinkingFault, now_s: float) -> None:
        """A linked group not read where expected: its reaction in FS, OS and AD."""
        applied = self._modes.mode in SUPERVISED_MODES
        event = LinkingEvent(
            time_s=now_s,
            balise_group_id=group.balise_group_id,
            expected_location_m=group.location_m,
            location_accuracy_m=group.location_accuracy_m,
            fault=fault,
            reaction=group.reaction,
            applied=applied,
        )
        self.linking_events.append(event)
        self._unreported.append(event)
        if not applied:
            return
        if group.reaction is LinkReaction.TRAIN_TRIP:
            self._modes.events.add(ModeCondition.LINKING_REACTION)
        elif group.reaction is LinkReaction.SERVICE_BRAKE:
            self._supervision.linking_brake = True

    def take_unreported(self) -> tuple[LinkingEvent, ...]:
        """The linking events since the last call, for the cycle's output."""
        events, self._unreported = tuple(self._unreported), []
        return events
