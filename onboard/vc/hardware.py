"""Emulated I/O of the Vital Control (seed 004 §2.1, §4.1): valves and brake pipe, radio relay,
tachometer board. Each is a deterministic function of simulated time and of its commands.

- :class:`EmergencyBrakeValves`: de-energising the solenoid valves vents the brake pipe, full
  EB being reached ``venting_s`` later (450 ms, seed 004); energising them recharges the pipe
  (the rearm) in ``recharge_s``. The EB digital input reads "released" once the valves are
  energised and the pipe is charged. A :class:`PipeFault` keeps the pipe from recharging (the
  rearm is not applied, scenario G).
- :class:`RadioRelay`: switches the ETCS-OB's power after ``switching_delay_s``; its contact is
  what the ETCS digital input re-reads. A :class:`RelayFault` keeps it from actuating
  (scenario F).
- :class:`TachometerBoard`: two tachometer channels on two axles, one frame every 80 ms
  (seed 004) with a frame number and each channel's pulse count. Faults: FROZEN (the last frame
  sent again and again), NOISY (channel B's count jumps at random), SILENT (no frame).

Pressures are fractions of the charged pipe (1 charged, 0 fully vented); the emulation does not
need bar.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

from onboard.vc._exceptions import VcInputError
from onboard.vc.config import TIME_TOLERANCE_S

__all__ = [
    "FRAME_NUMBER_MODULO",
    "FULL_EB_DELAY_S",
    "RECHARGE_S",
    "RELAY_SWITCHING_DELAY_S",
    "RELEASE_FRACTION",
    "EmergencyBrakeValves",
    "PipeFault",
    "RadioRelay",
    "RelayFault",
    "TachometerBoard",
    "TachometerFault",
    "TachometerFaultMode",
    "TachometerFrame",
    "ValveCommand",
]

FULL_EB_DELAY_S = 0.450
"""A standard pneumatic EB vents the pipe in at most 450 ms (seeds 001, 004)."""
RECHARGE_S = 1.0
"""⚠ Time to recharge the brake pipe after a rearm."""
RELEASE_FRACTION = 0.95
"""⚠ The EB input reads "released" above this fraction of the charged pressure."""
RELAY_SWITCHING_DELAY_S = 0.020
"""⚠ The radio relay's switching time."""
FRAME_NUMBER_MODULO = 65_536


def _check_window(start_s: float, end_s: float) -> None:
    if not (math.isfinite(start_s) and end_s > start_s):
        raise VcInputError(f"a fault window needs start < end, got {start_s}, {end_s}")


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise VcInputError(f"{name} must be positive and finite, got {value}")


@dataclass(frozen=True, kw_only=True)
class PipeFault:
    """Energising the valves in ``[start_s, end_s)`` does not recharge the pipe."""

    start_s: float
    end_s: float = math.inf

    def __post_init__(self) -> None:
        _check_window(self.start_s, self.end_s)


@dataclass(frozen=True, slots=True, kw_only=True)
class ValveCommand:
    time_s: float
    energised: bool
    pressure_fraction: float
    """The pipe's pressure when the command was given."""


class EmergencyBrakeValves:
    """The EB solenoid valves and the brake pipe they control.

    Parameters
    ----------
    venting_s
        From full pressure to full EB after de-energising [s] (450 ms by default).
    recharge_s
        From vented to charged after energising [s].
    energised
        State at power-up; de-energised (EB applied, pipe vented) by default.
    """

    def __init__(
        self,
        *,
        venting_s: float = FULL_EB_DELAY_S,
        recharge_s: float = RECHARGE_S,
        energised: bool = False,
        start_s: float = 0.0,
        faults: Sequence[PipeFault] = (),
    ) -> None:
        _positive("venting_s", venting_s)
        _positive("recharge_s", recharge_s)
        self.venting_s = venting_s
        self.recharge_s = recharge_s
        self.faults = tuple(faults)
        self._energised = energised
        self._pressure_0 = 1.0 if energised else 0.0
        self._time_0 = start_s
        self._rate = 0.0
        self.commands: list[ValveCommand] = []

    @property
    def energised(self) -> bool:
        return self._energised

    def pressure_fraction(self, now_s: float) -> float:
        """The pipe's pressure over the charged pressure, in [0, 1]."""
        pressure = self._pressure_0 + self._rate * (now_s - self._time_0)
        return min(1.0, max(0.0, pressure))

    def command(self, energised: bool, now_s: float) -> None:
        """Energise (rearm, release) or de-energise (apply the EB) the valves at ``now_s``."""
        if energised is self._energised:
            return
        pressure = self.pressure_fraction(now_s)
        self.commands.append(
            ValveCommand(time_s=now_s, energised=energised, pressure_fraction=pressure)
        )
        self._energised = energised
        self._pressure_0, self._time_0 = pressure, now_s
        if not energised:
            self._rate = -1.0 / self.venting_s
        elif any(f.start_s <= now_s < f.end_s for f in self.faults):
            self._rate = 0.0
        else:
            self._rate = 1.0 / self.recharge_s

    def release_change_s(self, now_s: float) -> float:
        """When the EB input, not released at ``now_s``, turns released with time alone (the
        pipe recharging past :data:`RELEASE_FRACTION`), a microsecond early (the input's own
        float sum may cross a little later); inf if it does not."""
        if not self._energised or self._rate <= 0.0 or self.eb_released(now_s):
            return math.inf
        return self._time_0 + (RELEASE_FRACTION - self._pressure_0) / self._rate - 1e-6

    def eb_released(self, now_s: float) -> bool:
        """The EB digital input: valves energised and the pipe charged."""
        return self._energised and self.pressure_fraction(now_s) >= RELEASE_FRACTION

    def brake_effort(self, now_s: float) -> float:
        """The EB's share of its full effort, in [0, 1]: the pipe's pressure drop."""
        return 1.0 - self.pressure_fraction(now_s)

    def full_emergency_brake_s(self, command: ValveCommand) -> float:
        """When a de-energising ``command`` reaches full EB (the pipe fully vented) [s]."""
        return command.time_s + command.pressure_fraction * self.venting_s


@dataclass(frozen=True, kw_only=True)
class RelayFault:
    """Commands given in ``[start_s, end_s)`` do not actuate the relay."""

    start_s: float
    end_s: float = math.inf

    def __post_init__(self) -> None:
        _check_window(self.start_s, self.end_s)


class RadioRelay:
    """The relay that powers the ETCS-OB (inserted) or not (isolated); seed 004, S7."""

    def __init__(
        self,
        *,
        inserted: bool = True,
        switching_delay_s: float = RELAY_SWITCHING_DELAY_S,
        faults: Sequence[RelayFault] = (),
    ) -> None:
        if not (math.isfinite(switching_delay_s) and switching_delay_s >= 0):
            raise VcInputError(f"switching delay must be finite, got {switching_delay_s}")
        self.switching_delay_s = switching_delay_s
        self.faults = tuple(faults)
        self._contact_inserted = inserted
        self._commanded_inserted = inserted
        self._pending: tuple[float, bool] | None = None
        self.commands: list[tuple[float, bool]] = []

    @property
    def commanded_inserted(self) -> bool:
        return self._commanded_inserted

    def command(self, inserted: bool, now_s: float) -> None:
        """Command the relay to insert (True) or isolate (False) the ETCS-OB at ``now_s``."""
        if inserted is self._commanded_inserted:
            return
        self._commanded_inserted = inserted
        self.commands.append((now_s, inserted))
        if any(f.start_s <= now_s < f.end_s for f in self.faults):
            self._pending = None
            return
        self._pending = (now_s + self.switching_delay_s, inserted)

    def pending_switch_s(self) -> float:
        """When the contact switches as last commanded [s] (inf: nothing pending)."""
        return self._pending[0] if self._pending is not None else math.inf

    def inserted(self, now_s: float) -> bool:
        """The contact as the ETCS digital input re-reads it at ``now_s``."""
        if self._pending is not None and self._pending[0] <= now_s + TIME_TOLERANCE_S:
            self._contact_inserted = self._pending[1]
            self._pending = None
        return self._contact_inserted


class TachometerFaultMode(StrEnum):
    FROZEN = "frozen"
    NOISY = "noisy"
    SILENT = "silent"


@dataclass(frozen=True, kw_only=True)
class TachometerFault:
    """The board misbehaves in ``[start_s, end_s)``."""

    mode: TachometerFaultMode
    start_s: float
    end_s: float = math.inf

    def __post_init__(self) -> None:
        _check_window(self.start_s, self.end_s)


@dataclass(frozen=True, slots=True)
class TachometerFrame:
    """One frame of the odometry board: its number and each channel's cumulative pulses."""

    frame_number: int
    pulses_a: int
    pulses_b: int


class TachometerBoard:
    """The odometry board (ATO-ODO): one frame every ``period_s`` from ``start_s``.

    Parameters
    ----------
    metres_per_pulse
        Wheel circumference over pulses a revolution [m].
    noise_pulses
        NOISY: channel B jumps by a random count in this range, either way, each frame.
    seed
        Seed of the noise, so that a run is repeatable.
    """

    def __init__(
        self,
        *,
        metres_per_pulse: float,
        period_s: float = 0.080,
        start_s: float = 0.0,
        faults: Sequence[TachometerFault] = (),
        noise_pulses: tuple[int, int] = (8, 16),
        seed: int = 0,
    ) -> None:
        _positive("metres_per_pulse", metres_per_pulse)
        _positive("period_s", period_s)
        self.metres_per_pulse = metres_per_pulse
        self.period_s = period_s
        self.start_s = start_s
        self.faults = tuple(faults)
        self.noise_pulses = noise_pulses
        self._random = random.Random(seed)
        self._sent = 0
        self._number = -1
        self._offset_b = 0
        self._last: TachometerFrame | None = None

    def _active(self, mode: TachometerFaultMode, now_s: float) -> bool:
        return any(f.mode is mode and f.start_s <= now_s < f.end_s for f in self.faults)

    def poll(
        self, now_s: float, distance_m: float, distance_b_m: float | None = None
    ) -> TachometerFrame | None:
        """The frame due at ``now_s``, if any is sent: channel A's axle having run
        ``distance_m`` [m] and channel B's ``distance_b_m`` [m] (the same axle's by default).

        On the vehicle the two channels sit on the two axles, so a slipping or sliding axle
        makes them disagree, as the VC's odometry supervision is meant to see."""
        if distance_b_m is None:
            distance_b_m = distance_m
        if now_s + TIME_TOLERANCE_S < self.start_s + self._sent * self.period_s:
            return None
        self._sent += 1
        self._number = (self._number + 1) % FRAME_NUMBER_MODULO
        if self._active(TachometerFaultMode.NOISY, now_s):
            low, high = self.noise_pulses
            self._offset_b += self._random.choice((-1, 1)) * self._random.randint(low, high)
        # Channel B's axle is half a pulse out of phase with channel A's.
        pulses_a = math.floor(distance_m / self.metres_per_pulse)
        pulses_b = math.floor(distance_b_m / self.metres_per_pulse + 0.5) + self._offset_b
        frame = TachometerFrame(self._number, pulses_a, pulses_b)
        if self._active(TachometerFaultMode.FROZEN, now_s) and self._last is not None:
            return self._last
        if self._active(TachometerFaultMode.SILENT, now_s):
            return None
        self._last = frame
        return frame
