"""Moving-block separation of the trains on a line: how far each train's EoA may reach.

The RBC knows each train on a line from its position reports (ETCS SUBSET-026 §3.6.5: the
estimated front end and the confidence interval around it). From the report and the train's
length it takes the train's **max safe front end** (the estimate plus the interval's
over-reading side) and its **min safe rear end** (the estimate less the interval's
under-reading side less the length). A train's EoA may reach no further than the min safe rear
end of the next train ahead on the line, less ``margin_m``: a moving block, the trains'
own reports bounding it, no fixed block sections (docs/decisions.md, "Separation: a moving
block").

Conventions, and their reasons:

- Trains run towards increasing chainage: the journeys of every line we hold do (a ring's
  lap included). "Ahead" on a ring wraps past the end of the lap.
- A report ages, but the rear it gave stays valid: a train in Full Supervision does not move
  backwards (ETCS supervises rollaway and reverse movement), so the last min safe rear end
  of a train whose reports stopped still bounds the train behind it, however old. A train
  taken off the line (:meth:`MovingBlock.remove`, at the end of its session or by the
  operator) no longer bounds anyone.
- A train that has not reported yet does not exist for the separation: the RBC grants no MA
  to a train it cannot place.

Nothing here reads a clock, opens a session or keeps history: :class:`MovingBlock` is fed
with reports and answers questions, in lockstep as in the service.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

from protocol import messages as m

__all__ = ["MovingBlock", "TrainExtent", "extent_from_report"]


@dataclass(frozen=True, slots=True)
class TrainExtent:
    """Where one train may be, from its last report (chainages on its line [m])."""

    vehicle_id: str
    line_id: str
    front_m: float
    """Max safe front end: the estimated front end plus the confidence interval."""
    rear_m: float
    """Min safe rear end: the estimated front end less the interval and the train's length."""
    reported_at_s: float
    """The report's time on the RBC's clock [s]."""


def extent_from_report(
    report: m.StatusReport, *, train_length_m: float, received_at_s: float
) -> TrainExtent:
    """The extent a status report gives a train of ``train_length_m`` [m].

    A report without a confidence interval (no ETCS position yet) is taken as exact: the
    RBC's own margin then covers the estimate's error alone.
    """
    if not (math.isfinite(train_length_m) and train_length_m > 0.0):
        raise ValueError(f"train length {train_length_m} m must be finite and positive")
    confidence = report.position_confidence_m or 0.0
    return TrainExtent(
        vehicle_id=report.vehicle_id,
        line_id=report.line_id,
        front_m=report.position_m + confidence,
        rear_m=report.position_m - confidence - train_length_m,
        reported_at_s=received_at_s,
    )


class MovingBlock:
    """The trains on each line and the reach each one's EoA may have.

    Parameters
    ----------
    margin_m
        The distance [m] kept between an EoA and the min safe rear end of the train ahead.
    ring_length_m
        A ring line's length [m] by its id, None for an open line: "ahead" wraps there.
        Without it every line is open.
    """

    def __init__(
        self, *, margin_m: float, ring_length_m: Callable[[str], float | None] | None = None
    ) -> None:
        if not (math.isfinite(margin_m) and margin_m >= 0.0):
            raise ValueError(f"margin {margin_m} m must be finite and ≥ 0")
        self.margin_m = margin_m
        self._ring_length = ring_length_m
        self._lock = threading.Lock()
        self._extents: dict[str, TrainExtent] = {}

    def update(self, extent: TrainExtent) -> None:
        """Take a train's latest extent (from :func:`extent_from_report`).

        A rear end behind the one the train last reported on the same line is kept at the
        last: the train did not move backwards, its estimate did (a balise's correction, a
        wider interval), and the train behind was already granted up to the old one.
        """
        with self._lock:
            last = self._extents.get(extent.vehicle_id)
            if (
                last is not None
                and last.line_id == extent.line_id
                and self._signed_ahead_m(extent.line_id, last.rear_m, extent.rear_m) < 0.0
            ):
                extent = TrainExtent(
                    vehicle_id=extent.vehicle_id,
                    line_id=extent.line_id,
                    front_m=extent.front_m,
                    rear_m=last.rear_m,
                    reported_at_s=extent.reported_at_s,
                )
            self._extents[extent.vehicle_id] = extent

    def remove(self, vehicle_id: str) -> None:
        """Take a train off the line: it bounds no train behind it any more."""
        with self._lock:
            self._extents.pop(vehicle_id, None)

    def extent(self, vehicle_id: str) -> TrainExtent | None:
        with self._lock:
            return self._extents.get(vehicle_id)

    def trains(self, line_id: str) -> list[TrainExtent]:
        """The trains on the line, in no particular order."""
        with self._lock:
            return [e for e in self._extents.values() if e.line_id == line_id]

    def train_ahead(self, vehicle_id: str) -> TrainExtent | None:
        """The next train ahead of the train's max safe front end on its line; None if none
        (or the train is unknown)."""
        with self._lock:
            own = self._extents.get(vehicle_id)
            if own is None:
                return None
            return self._next_ahead(own)

    def gap_m(self, vehicle_id: str) -> float:
        """From the train's max safe front end to the min safe rear end of the train ahead
        [m]: +inf with none ahead, negative when the two overlap (reports that cannot both be
        right: the RBC then grants nothing beyond the front end)."""
        with self._lock:
            own = self._extents.get(vehicle_id)
            if own is None:
                return math.inf
            ahead = self._next_ahead(own)
            if ahead is None:
                return math.inf
            between_rears = self.ahead_m(own.line_id, own.rear_m, ahead.rear_m)
            return between_rears - (own.front_m - own.rear_m)

    def limit_m(self, vehicle_id: str) -> float | None:
        """The furthest chainage [m] the train's EoA may reach, on the train's own lap (its
        reported front end plus the gap less the margin); +inf with no train ahead, None for
        a train the separation does not know."""
        with self._lock:
            own = self._extents.get(vehicle_id)
        if own is None:
            return None
        return own.front_m + self.gap_m(vehicle_id) - self.margin_m

    # -- internals ----------------------------------------------------------------------------

    def ring_length_m(self, line_id: str) -> float | None:
        """The line's length [m] if it is a ring; None for an open line.

        Raises
        ------
        ValueError
            If the lookup gives a length that is not finite and positive.
        """
        length = None if self._ring_length is None else self._ring_length(line_id)
        if length is not None and not (math.isfinite(length) and length > 0.0):
            raise ValueError(f"ring {line_id!r}: length {length} m must be positive")
        return length

    def ahead_m(self, line_id: str, from_m: float, to_m: float) -> float:
        """How far ``to_m`` lies ahead of ``from_m`` on the line [m]: on a ring, within one lap
        ([0, length)); on an open line, negative behind."""
        length = self.ring_length_m(line_id)
        if length is None:
            return to_m - from_m
        return (to_m - from_m) % length

    def _signed_ahead_m(self, line_id: str, from_m: float, to_m: float) -> float:
        """As :meth:`_ahead_m`, but on a ring within (−½ lap, ½ lap]: a rear a little behind
        the front is an overlap, not a train almost a lap ahead."""
        ahead = self.ahead_m(line_id, from_m, to_m)
        length = self.ring_length_m(line_id)
        if length is not None and ahead > 0.5 * length:
            ahead -= length
        return ahead

    def _next_ahead(self, own: TrainExtent) -> TrainExtent | None:
        """The train whose rear end lies nearest ahead of ``own``'s rear end (trains are
        ordered by their rear ends: two overlapping reports are still ordered; two with the
        same rear end bound neither)."""
        best: TrainExtent | None = None
        best_m = math.inf
        for other in self._extents.values():
            if other.vehicle_id == own.vehicle_id or other.line_id != own.line_id:
                continue
            ahead = self.ahead_m(own.line_id, own.rear_m, other.rear_m)
            if 0.0 < ahead < best_m:
                best, best_m = other, ahead
        return best
