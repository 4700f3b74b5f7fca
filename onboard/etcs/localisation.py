"""Where the train is, for :class:`onboard.etcs.EtcsOnboard` (SUBSET-026 §3.4, §3.6).

:class:`Localisation` holds the odometer's position in the onboard's track coordinate, the
confidence interval around the estimated front end (:mod:`onboard.etcs.odometry`), its
relocation at each balise group read, and the linked groups' expectation windows
(:mod:`onboard.etcs.linking`). The position comes one of two ways:

- given: the odometer's chainage, speed and A_est (:meth:`Localisation.move`); on a ring the
  chainage is unwrapped near the last one;
- on the train's sensors: the wheel readings (:meth:`Localisation.sense`), counted by the
  :class:`~onboard.etcs.odometer.Odometer` from the start position, with the slip/slide
  allowances it adds to the interval; a balise detection is placed at the odometer's position
  interpolated to its time (:meth:`Localisation.detection_position`).

The packets a group delivers, the modes and the linking reactions are the onboard's business.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from onboard.etcs.balises import LinkedGroup
from onboard.etcs.linking import LinkingFault, LinkingSupervision
from onboard.etcs.odometer import Odometer, OdometerOutput, WheelAdhesion
from onboard.etcs.odometry import ConfidenceInterval, Odometry, OdometryAccuracy
from onboard.plant.readings import WheelReading
from trackdb import TrackMap

__all__ = ["Localisation", "OdometerPoint"]


@dataclass(frozen=True, kw_only=True)
class OdometerPoint:
    """The odometer's position [m] in the track coordinate and its slip/slide allowances
    (ahead, behind) [m], cumulative since the start."""

    odometer_m: float
    slip_slide_over_m: float = 0.0
    slip_slide_under_m: float = 0.0


class Localisation:
    """The odometer's position, the confidence interval, the LRBG and the linking windows.

    Parameters
    ----------
    track_map : TrackMap
        The line (its length, on a ring).
    accuracy : OdometryAccuracy
        The odometer's error law.
    position_m : float
        The front end's chainage [m] at start: the odometer's zero.
    location_accuracy_m : float
        The start position's accuracy [m] (Q_NVLOCACC).
    odometer : Odometer, optional
        The wheel-sensor odometer of the sensor path.
    """

    def __init__(
        self,
        track_map: TrackMap,
        accuracy: OdometryAccuracy,
        *,
        position_m: float,
        location_accuracy_m: float,
        odometer: Odometer | None = None,
    ) -> None:
        self.track_map = track_map
        self.odometer = odometer
        self.linking = LinkingSupervision()
        self.lrbg_id: int | None = None
        self.speed_mps = 0.0
        self.acceleration_mps2 = 0.0
        self._start_m = position_m
        self._chainage_m = position_m
        self._point = OdometerPoint(odometer_m=position_m)
        self._odometry = Odometry(
            accuracy, odometer_m=position_m, location_accuracy_m=location_accuracy_m
        )
        self._interval = self._odometry.interval

    @property
    def interval(self) -> ConfidenceInterval:
        """The confidence interval at the odometer's last position."""
        return self._interval

    @property
    def odometer_m(self) -> float:
        """The odometer's last position [m] in the track coordinate."""
        return self._point.odometer_m

    @property
    def adhesion(self) -> WheelAdhesion:
        """Slip or slide as the odometer sees it; rolling on the given-motion path."""
        return WheelAdhesion.ROLLING if self.odometer is None else self.odometer.output.adhesion

    def move(self, position_m: float, speed_mps: float, acceleration_mps2: float) -> None:
        """The odometer is at chainage ``position_m`` [m], speed [m/s] and A_est [m/s²]."""
        self._point = OdometerPoint(odometer_m=self.unwrap(position_m))
        self._chainage_m = position_m
        self.speed_mps, self.acceleration_mps2 = speed_mps, acceleration_mps2

    def sense(self, odometer: Odometer, wheels: Sequence[WheelReading]) -> OdometerOutput:
        """Count the wheel readings since the last cycle."""
        out = odometer.update(wheels)
        self._point = OdometerPoint(
            odometer_m=self._start_m + out.distance_m,
            slip_slide_over_m=out.slip_slide_over_m,
            slip_slide_under_m=out.slip_slide_under_m,
        )
        self.speed_mps, self.acceleration_mps2 = out.speed_mps, out.acceleration_mps2
        return out

    def detection_position(self, odometer: Odometer, time_s: float) -> OdometerPoint:
        """Where the odometer was at ``time_s`` [s] (a balise detection's time)."""
        at = odometer.position_at(time_s)
        return OdometerPoint(
            odometer_m=self._start_m + at.distance_m,
            slip_slide_over_m=at.slip_slide_over_m,
            slip_slide_under_m=at.slip_slide_under_m,
        )

    def update(self) -> ConfidenceInterval:
        """The interval at the odometer's last position."""
        self._interval = self._interval_at(self._point, keep=True)
        return self._interval

    def unwrap(self, chainage_m: float) -> float:
        """An odometer chainage as a track location, unwrapped near the last one."""
        if not self.track_map.line.ring:
            return chainage_m
        length_m = self.track_map.length_m
        delta_m = (chainage_m - self._chainage_m + length_m / 2.0) % length_m
        return self._point.odometer_m + delta_m - length_m / 2.0

    def locate(self, chainage_m: float) -> float:
        """A chainage as the track location nearest the estimated front end."""
        if not self.track_map.line.ring:
            return chainage_m
        length_m = self.track_map.length_m
        near_m = self._interval.estimated_front_m
        return chainage_m + length_m * round((near_m - chainage_m) / length_m)

    def locate_span(self, start_m: float, length_m: float) -> float:
        """Where a stretch of the line from chainage ``start_m``, ``length_m`` [m] long (an
        MA from its reference), starts: on a ring, the lap on which the estimated front end
        lies inside it, or nearest to it.

        An RBC's MA may reference a location most of a lap behind the train (its start when
        first issued, kept by its extensions): the location nearest the front end would then
        be the next lap's, and the EoA a lap too far.
        """
        if not self.track_map.line.ring:
            return start_m
        lap_m = self.track_map.length_m
        front_m = self._interval.estimated_front_m
        nearest = self.locate(start_m)
        candidates = (nearest, nearest - lap_m, nearest + lap_m)  # ties: the nearest
        return min(candidates, key=lambda at: _outside_m(front_m, at, at + length_m))

    def relocate(
        self,
        balise_group_id: int,
        location_m: float,
        *,
        at: OdometerPoint,
        location_accuracy_m: float,
        linked_groups: Sequence[LinkedGroup],
    ) -> list[tuple[LinkedGroup, LinkingFault]]:
        """A group at ``location_m`` [m] read when the odometer was ``at``: it becomes the
        LRBG, the interval restarts from ``location_accuracy_m`` [m] and its linking replaces
        the announcements. Returns the linked groups this reading shows not where expected."""
        faults = self.linking.group_read(
            balise_group_id, location_m, self._interval_at(at, keep=False)
        )
        self._odometry.reset(
            location_m=location_m,
            odometer_m=at.odometer_m,
            location_accuracy_m=location_accuracy_m,
            slip_slide_over_m=at.slip_slide_over_m,
            slip_slide_under_m=at.slip_slide_under_m,
        )
        self.update()
        self.lrbg_id = balise_group_id
        self.linking.expect(linked_groups)
        return faults

    def missed_groups(self) -> list[tuple[LinkedGroup, LinkingFault]]:
        """The linked groups whose window the min-safe front end has passed unread."""
        return self.linking.passed(self._interval)

    def _interval_at(self, point: OdometerPoint, *, keep: bool) -> ConfidenceInterval:
        over_m, under_m = point.slip_slide_over_m, point.slip_slide_under_m
        if keep:
            return self._odometry.update(
                point.odometer_m, slip_slide_over_m=over_m, slip_slide_under_m=under_m
            )
        return self._odometry.interval_at(
            point.odometer_m, slip_slide_over_m=over_m, slip_slide_under_m=under_m
        )


def _outside_m(position_m: float, start_m: float, end_m: float) -> float:
    """How far ``position_m`` lies outside ``[start_m, end_m]`` [m] (0 inside)."""
    return max(start_m - position_m, position_m - end_m, 0.0)
