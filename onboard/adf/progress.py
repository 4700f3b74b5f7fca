"""Journey progress: where the train stands on the journey the ADF drives.

The journey's stops are distances travelled from its origin (the plant's distance travelled [m]
and the node's time [s] where and when it started, ``JourneyPlan``). This module keeps that
origin, which stops have been served (stopped at, passed or skipped), the ones the driver asked
to run through ("Skip Stopping Point") and the departures a late arrival delayed; it answers the
stack's and the status report's questions (the next stop, the stop the train stands at, the
overrun, the departure, the arrival estimates). The leg replanning (``onboard.adf.replanning``)
and the driving function (``onboard.adf.function``) read it.
"""

from __future__ import annotations

import math

from onboard.adf.journey import JourneyPlan, JourneyStop
from onboard.adf.odp import OdpPlan

__all__ = ["JourneyProgress"]

STOP_TOLERANCE_M = 1.0
"""Standing this close to a stopping point [m] is standing at it."""
STANDSTILL_MPS = 0.01
PASSED_M = 10.0
"""A stop this far behind the front end [m] is passed. Standing between the stop's tolerance and
this far past it is an overrun: the train has stopped there (it does not run back), and the
stack reports the overrun."""
ARRIVAL_RESOLUTION_S = 1e-3
"""How closely the arrival estimates find the time of the reference at the vehicle [s]."""
DELAY_PROBE_M = 0.5


class JourneyProgress:
    """The journey being driven, its origin, and the stops served, skipped and delayed."""

    def __init__(self) -> None:
        self.journey: JourneyPlan | None = None
        self.origin_m = 0.0
        """Where the journey started, in the plant's distance travelled [m]."""
        self.origin_s = 0.0
        """When the journey started [s]."""
        self.served = 0
        """How many stops of the journey have been served (stopped at, or passed)."""
        self.skipped: set[str] = set()
        """Timing points the driver asked to run through ("Skip Stopping Point"); kept from
        before a journey starts (a skip sent before engaging), cleared for a new journey by its
        keeper."""
        self._departures_s: dict[str, float] = {}
        """Departures delayed by a late arrival, by timing point [s from the journey's start]."""

    def start(self, journey: JourneyPlan, now_s: float, *, position_m: float) -> None:
        """Make ``journey`` the one driven: its time and distance start here and now."""
        self.journey = journey
        self.origin_m, self.origin_s = position_m, now_s
        self.served = 0
        self._departures_s.clear()

    def travelled_m(self, position_m: float) -> float:
        """The distance [m] from the journey's origin to ``position_m``."""
        return position_m - self.origin_m

    def journey_time_s(self, now_s: float) -> float:
        """The time [s] since the journey started."""
        return now_s - self.origin_s

    def next_stop(self, position_m: float) -> JourneyStop | None:
        """The first stop of the journey not yet served (stopped at, or passed)."""
        if self.journey is None:
            return None
        self.update_served(position_m, speed_mps=math.inf)
        return next(iter(self._stops_ahead()), None)

    def _stops_ahead(self) -> list[JourneyStop]:
        """The stops not yet served, the skipped ones left out."""
        assert self.journey is not None
        return [
            s for s in self.journey.stops[self.served :] if s.timing_point_id not in self.skipped
        ]

    def update_served(self, position_m: float, speed_mps: float) -> None:
        """Count the stops served at ``position_m`` [m] and ``speed_mps`` [m/s]: stopped at,
        passed, or skipped and run through."""
        if self.journey is None:
            return
        travelled = position_m - self.origin_m
        stops = self.journey.stops
        while self.served < len(stops):
            stop = stops[self.served]
            stopped = speed_mps <= STANDSTILL_MPS and _stands_at(stop, travelled)
            skipped = stop.timing_point_id in self.skipped and travelled > stop.distance_m
            if not (stopped or skipped or travelled > stop.distance_m + PASSED_M):
                return
            self.served += 1

    def arrival_estimates(
        self, plan: OdpPlan, now_s: float, position_m: float
    ) -> list[tuple[JourneyStop, float]]:
        """For each stop not yet served: the stop and its estimated arrival [s from the journey's
        start], the schedule shifted by the current delay against ``plan``, the one followed
        (never early: the plan keeps the schedule)."""
        self.update_served(position_m, speed_mps=math.inf)
        journey_s = now_s - self.origin_s
        ahead = position_m - self.origin_m + DELAY_PROBE_M
        low, high = plan.legs[0].start_s, plan.end_s
        if plan.reference(high)[0] < ahead:
            reference_s = high
        else:
            while high - low > ARRIVAL_RESOLUTION_S:  # when the reference passes the vehicle
                middle = 0.5 * (low + high)
                low, high = (middle, high) if plan.reference(middle)[0] < ahead else (low, middle)
            reference_s = high
        delay = max(journey_s - reference_s, 0.0)
        return [(stop, max(stop.arrival_s + delay, journey_s)) for stop in self._stops_ahead()]

    def overrun_m(self, stop: JourneyStop, position_m: float) -> float:
        """How far the front end at ``position_m`` stands past ``stop`` beyond its tolerance [m]
        (0 when within it or short of it)."""
        past_m = position_m - self.origin_m - stop.distance_m
        return max(past_m - STOP_TOLERANCE_M, 0.0)

    def stopped_at(self, position_m: float, speed_mps: float) -> JourneyStop | None:
        """The stop of the journey the vehicle stands at, if any."""
        if self.journey is None or speed_mps > STANDSTILL_MPS:
            return None
        travelled = position_m - self.origin_m
        for stop in self.journey.stops:
            if stop.timing_point_id in self.skipped:
                continue
            if _stands_at(stop, travelled):
                return stop
        return None

    def stop_near(self, distance_m: float) -> JourneyStop | None:
        """The journey's stop within its tolerance of ``distance_m`` [m from the origin]."""
        assert self.journey is not None
        return next(
            (s for s in self.journey.stops if abs(s.distance_m - distance_m) <= STOP_TOLERANCE_M),
            None,
        )

    def departure_s(self, stop: JourneyStop) -> float:
        """When the plan leaves ``stop`` [s from the journey's start]: its scheduled departure,
        or later when the train arrived late and the stop keeps its dwell."""
        return self._departures_s.get(stop.timing_point_id, stop.departure_s)

    def delay_departure(self, stop: JourneyStop, departure_s: float | None) -> None:
        """Leave ``stop`` at ``departure_s`` [s from the journey's start], or on its schedule
        when None."""
        if departure_s is None:
            self._departures_s.pop(stop.timing_point_id, None)
        else:
            self._departures_s[stop.timing_point_id] = departure_s


def _stands_at(stop: JourneyStop, travelled_m: float) -> bool:
    """At ``travelled_m`` [m] from the journey's origin the front end stands at ``stop``: within
    its tolerance, or past it by less than :data:`PASSED_M` (an overrun)."""
    return -STOP_TOLERANCE_M <= travelled_m - stop.distance_m <= PASSED_M
