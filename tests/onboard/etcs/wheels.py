"""A test double of the plant's wheel sensors and balise reader, with a known truth.

``WheelRig`` moves a train along a straight track every 10 ms at the accelerations asked, and
gives what the axle-end sensors read (each axle's travel and speed through its calibrated
wheel: a diameter error reads long or short, a slipping or sliding wheel turns at the speed
the test says) and the balise groups the reader locates, each at the instant the front end was
at the group plus the reader's location error. ``drive`` feeds an onboard every 100 ms.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from onboard.etcs import EtcsOnboard, EtcsOutput
from onboard.plant.readings import BaliseDetection, WheelReading
from trackdb import BaliseGroup

__all__ = ["DT_WHEELS_S", "Cycle", "WheelRig"]

DT_WHEELS_S = 0.01
WheelSpeeds = Callable[[float, float], tuple[float, float]]
"""(time [s], true speed [m/s]) → each axle's circumferential speed [m/s], front and rear."""


def _rolling(_time_s: float, speed_mps: float) -> tuple[float, float]:
    return speed_mps, speed_mps


@dataclass(frozen=True)
class Cycle:
    """One ETCS cycle: its output and the truth at its time."""

    output: EtcsOutput
    true_front_m: float
    true_speed_mps: float


@dataclass
class WheelRig:
    """The truth of a train and its sensors' readings.

    ``reads_long_front`` / ``reads_long_rear``: how much longer than the ground each axle's
    calibrated wheel reads (0.02: a wheel worn 2 % below its calibrated diameter).
    ``reader_errors_m``: the reader's location error of each successive detection [m].
    """

    position_m: float
    speed_mps: float = 0.0
    time_s: float = 0.0
    reads_long_front: float = 0.0
    reads_long_rear: float = 0.0
    groups: Sequence[BaliseGroup] = ()
    missed_ids: frozenset[int] = frozenset()
    reader_errors_m: Sequence[float] = ()
    travel_front_m: float = 0.0
    travel_rear_m: float = 0.0
    _detected: int = 0
    _seen: set[int] = field(default_factory=set)
    _started: bool = False

    def reading(self, front_mps: float, rear_mps: float) -> WheelReading:
        return WheelReading(
            time_s=self.time_s,
            travel_front_m=self.travel_front_m,
            travel_rear_m=self.travel_rear_m,
            speed_front_mps=front_mps * (1.0 + self.reads_long_front),
            speed_rear_mps=rear_mps * (1.0 + self.reads_long_rear),
        )

    def advance(
        self, acceleration_mps2: float, wheels: WheelSpeeds = _rolling
    ) -> tuple[WheelReading, list[BaliseDetection]]:
        """10 ms at ``acceleration_mps2`` (the speed stays ≥ 0)."""
        start_m, start_mps = self.position_m, self.speed_mps
        self.speed_mps = max(start_mps + acceleration_mps2 * DT_WHEELS_S, 0.0)
        self.position_m += 0.5 * (start_mps + self.speed_mps) * DT_WHEELS_S
        front_mps, rear_mps = wheels(self.time_s + DT_WHEELS_S, self.speed_mps)
        before_front, before_rear = wheels(self.time_s, start_mps)
        self.travel_front_m += (
            0.5 * (before_front + front_mps) * DT_WHEELS_S * (1.0 + self.reads_long_front)
        )
        self.travel_rear_m += (
            0.5 * (before_rear + rear_mps) * DT_WHEELS_S * (1.0 + self.reads_long_rear)
        )
        detections = self._detections(start_m)
        self.time_s += DT_WHEELS_S
        return self.reading(front_mps, rear_mps), detections

    def _detections(self, start_m: float) -> list[BaliseDetection]:
        found: list[BaliseDetection] = []
        for group in self.groups:
            if group.id in self._seen:
                continue
            error_m = 0.0
            if self._detected < len(self.reader_errors_m):
                error_m = self.reader_errors_m[self._detected]
            at_m = group.position_m + error_m
            if start_m < at_m <= self.position_m:
                self._seen.add(group.id)
                if group.id in self.missed_ids:
                    continue
                self._detected += 1
                share = (at_m - start_m) / (self.position_m - start_m)
                found.append(BaliseDetection(self.time_s + share * DT_WHEELS_S, group))
        return found

    def drive(
        self,
        etcs: EtcsOnboard,
        duration_s: float,
        acceleration_mps2: float = 0.0,
        wheels: WheelSpeeds = _rolling,
    ) -> list[Cycle]:
        """Run ``duration_s`` [s], the onboard stepped every 100 ms on what the sensors read."""
        cycles: list[Cycle] = []
        for _ in range(round(duration_s / 0.1)):
            readings: list[WheelReading] = []
            if not self._started:
                # The sensors' reading at power-up: the odometer's zero.
                self._started = True
                readings.append(self.reading(*wheels(self.time_s, self.speed_mps)))
            detections: list[BaliseDetection] = []
            for _ in range(10):
                reading, found = self.advance(acceleration_mps2, wheels)
                readings.append(reading)
                detections.extend(found)
            output = etcs.step_on_sensors(round(self.time_s, 9), readings, detections)
            cycles.append(Cycle(output, self.position_m, self.speed_mps))
        return cycles
