"""Linking: the balise groups announced next, and the reaction when one is not where expected.

SUBSET-026 §3.4.4 (DOMAIN.md §1.6 condition [17], §1.7 packet 5). A group's linking
information (packet 5) announces the next groups: each with its distance D_LINK from the group,
its location accuracy Q_LOCACC and the reaction Q_LINKREACTION. Each announced group has an
expectation window, its expected location ± Q_LOCACC. Because the train knows its own location
only within its odometry confidence interval, the onboard compares the window with that
interval:

- **missed**: the min-safe front end has passed the window's end (the train is surely beyond
  the group) without reading it, or a group lying beyond the expected location was read
  first;
- **outside the window**: the group was read while the interval and the window did not
  overlap (it cannot be where the train thinks it is).

Either way the linking reaction of that group applies (trackdb's ``LinkReaction``):

- ``train_trip``: the train trips, FS/OS/AD → TR, condition [17];
- ``service_brake``: the service brake is commanded (the EB where the train has none) and held
  to standstill (⚠ SUBSET-026 lets a driver release it; an unattended train has none);
- ``no_reaction``: nothing, the event is only reported.

Reactions apply in FS, OS and AD (⚠ not in SR, SB, PT, TR; in IS nothing is checked); the
event is reported in every mode but IS. A group read outside its window still becomes the
LRBG (⚠). An announcement is dropped once its group is read or its reaction taken, and every
announcement is replaced by the next group's linking.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

from onboard.etcs.balises import LinkedGroup
from onboard.etcs.odometry import ConfidenceInterval
from trackdb.schema import LinkReaction

__all__ = ["LinkingEvent", "LinkingFault", "LinkingSupervision"]


class LinkingFault(StrEnum):
    """How a linked group failed to be where it was expected."""

    MISSED = "missed"
    OUTSIDE_WINDOW = "outside_window"


@dataclass(frozen=True, kw_only=True)
class LinkingEvent:
    """A linked balise group not read where expected, and what the onboard did about it."""

    time_s: float
    balise_group_id: int
    expected_location_m: float
    """The group's expected location [m] in the onboard's track coordinate."""
    location_accuracy_m: float
    """Q_LOCACC [m]: the window is the expected location ± this."""
    fault: LinkingFault
    reaction: LinkReaction
    """Q_LINKREACTION of the announcement."""
    applied: bool
    """Whether the reaction was taken (FS, OS, AD) or only reported."""


class LinkingSupervision:
    """The groups announced by the LRBG's linking, and the check of their windows."""

    def __init__(self) -> None:
        self._expected: dict[int, LinkedGroup] = {}

    @property
    def expected(self) -> tuple[LinkedGroup, ...]:
        """The announced groups not read yet."""
        return tuple(self._expected.values())

    def announcement(self, balise_group_id: int) -> LinkedGroup | None:
        """The announcement of this group, if the LRBG's linking made one."""
        return self._expected.get(balise_group_id)

    def expect(self, groups: Sequence[LinkedGroup]) -> None:
        """A group's linking information replaces the announcements."""
        self._expected = {group.balise_group_id: group for group in groups}

    def group_read(
        self, balise_group_id: int, location_m: float, interval: ConfidenceInterval
    ) -> list[tuple[LinkedGroup, LinkingFault]]:
        """A group at ``location_m`` [m] read when the train's interval was ``interval``.

        Returns the announced groups this reading shows missed, or the group itself if it was
        read outside its window. The caller then replaces the announcements.
        """
        faults = [
            (group, LinkingFault.MISSED)
            for group in self._expected.values()
            if group.balise_group_id != balise_group_id and group.location_m < location_m
        ]
        announced = self._expected.get(balise_group_id)
        if announced is not None and not _overlaps(announced, interval):
            faults.append((announced, LinkingFault.OUTSIDE_WINDOW))
        return faults

    def passed(self, interval: ConfidenceInterval) -> list[tuple[LinkedGroup, LinkingFault]]:
        """The announced groups whose window's end the min-safe front end has passed; they are
        dropped from the announcements."""
        missed = [
            group
            for group in self._expected.values()
            if interval.min_safe_front_m > group.location_m + group.location_accuracy_m
        ]
        for group in missed:
            del self._expected[group.balise_group_id]
        return [(group, LinkingFault.MISSED) for group in missed]


def _overlaps(group: LinkedGroup, interval: ConfidenceInterval) -> bool:
    return (
        interval.max_safe_front_m >= group.location_m - group.location_accuracy_m
        and interval.min_safe_front_m <= group.location_m + group.location_accuracy_m
    )
