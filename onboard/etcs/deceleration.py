"""Deceleration along the track: A_safe and A_expected (SUBSET-026 §3.13.4, §3.13.6; DOMAIN §1.4).

::

    A_safe       = A_brake_safe + A_gradient
    A_expected   = A_brake_service + A_gradient
    A_brake_safe = Kdry_rst·(Kwet_rst + M_NVAVADH·(1 − Kwet_rst))·A_brake_emergency   gamma train
                 = Kv_int·Kr_int·A_brake_emergency                                    lambda train
    A_gradient   = g·grad / (1000 + 10·M_rotating)       grad [‰], positive uphill

M_rotating is the train's nominal rotating mass [%] when known; otherwise M_rotating_max applies
uphill and M_rotating_min downhill, which makes A_gradient the least favourable. The gradient
that applies at a front-end location x is the lowest one under the train, over [x − L, x].

A :class:`DecelerationProfile` is the result: a step function of the front end's location [m],
in the onboard's track coordinate (chainage, unwrapped on a ring). It is built from the TrackMap's
gradient profile over a window; before the window its first value holds, after it its last.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence

from onboard.etcs._exceptions import BrakingCapabilityError, EtcsInputError
from onboard.etcs.values import BrakeModelType, FixedValues, NationalValues, TrainData
from protocol.units import GRAVITY_MPS2
from trackdb import TrackMap

__all__ = [
    "GRAVITY_MPS2",
    "DecelerationProfile",
    "GradientStep",
    "brake_safe_deceleration_mps2",
    "gradient_acceleration_mps2",
    "gradient_steps",
    "lowest_gradient_under_train",
]

GradientStep = tuple[float, float, float]
"""(from [m], to [m], gradient [‰]) over ``[from, to)``, in the track coordinate."""


def brake_safe_deceleration_mps2(train: TrainData, national: NationalValues) -> float:
    """A_brake_safe [m/s²] of the train, before the gradient."""
    if train.brake_model is BrakeModelType.LAMBDA:
        return national.kv_int * national.kr_int * train.a_brake_emergency_mps2
    wet = train.kwet_rst + national.m_nvavadh * (1.0 - train.kwet_rst)
    return train.kdry_rst * wet * train.a_brake_emergency_mps2


def gradient_acceleration_mps2(
    gradient_permille: float, *, fixed: FixedValues, rotating_mass_percent: float | None = None
) -> float:
    """A_gradient [m/s²]: adds to the deceleration uphill (gradient > 0), subtracts downhill."""
    if rotating_mass_percent is None:
        rotating_mass_percent = (
            fixed.m_rotating_max_percent if gradient_permille > 0 else fixed.m_rotating_min_percent
        )
    return GRAVITY_MPS2 * gradient_permille / (1000.0 + 10.0 * rotating_mass_percent)


def gradient_steps(track_map: TrackMap, start_m: float, end_m: float) -> list[GradientStep]:
    """The line's gradient over ``[start_m, end_m)`` [m] of the track coordinate.

    On a ring the coordinate runs on across the origin (lap after lap); on an open line the
    first section's gradient holds before the origin and the last one's beyond the end.
    """
    if not (math.isfinite(start_m) and math.isfinite(end_m) and start_m < end_m):
        raise EtcsInputError(f"gradient window {start_m}..{end_m} m is not a finite range")
    sections = track_map.line.gradient_permille
    length_m = track_map.length_m
    steps: list[GradientStep] = []
    if track_map.line.ring:
        for lap in range(math.floor(start_m / length_m), math.floor(end_m / length_m) + 1):
            offset_m = lap * length_m
            for section in sections:
                low = max(section.start_m + offset_m, start_m)
                high = min(section.end_m + offset_m, end_m)
                if low < high:
                    steps.append((low, high, section.value))
    else:
        if start_m < 0.0:
            steps.append((start_m, min(0.0, end_m), sections[0].value))
        for section in sections:
            low, high = max(section.start_m, start_m), min(section.end_m, end_m)
            if low < high:
                steps.append((low, high, section.value))
        if end_m > length_m:
            steps.append((max(length_m, start_m), end_m, sections[-1].value))
    return _merged(steps)


def _merged(steps: list[GradientStep]) -> list[GradientStep]:
    merged: list[GradientStep] = []
    for step in steps:
        if merged and merged[-1][2] == step[2] and merged[-1][1] == step[0]:
            merged[-1] = (merged[-1][0], step[1], step[2])
        else:
            merged.append(step)
    return merged


def lowest_gradient_under_train(
    steps: Sequence[GradientStep], train_length_m: float
) -> list[GradientStep]:
    """The gradient that applies to each front-end location: the lowest over [x − L, x].

    ``steps`` must be contiguous; before the first the first gradient holds. The result is a
    step function over the same range; it changes only where a step boundary meets the front
    end or the rear end, so those points are the candidates.
    """
    if not steps:
        return []
    if train_length_m < 0:
        raise EtcsInputError("train length must not be negative")
    start_m, end_m = steps[0][0], steps[-1][1]
    cuts = {start_m}
    for low, _, _ in steps:
        cuts.update(point for point in (low, low + train_length_m) if start_m <= point < end_m)
    ordered = sorted(cuts)
    result: list[GradientStep] = []
    for low, high in zip(ordered, [*ordered[1:], end_m], strict=True):
        middle = 0.5 * (low + high)
        rear = middle - train_length_m
        # Before the first step its gradient holds, so a window reaching back past the start
        # still meets the first step.
        lowest = min(
            gradient
            for step_low, step_high, gradient in steps
            if step_low <= middle and step_high > rear
        )
        result.append((low, high, lowest))
    return _merged(result)


class DecelerationProfile:
    """Deceleration [m/s²] as a step function of the front end's location [m].

    Parameters
    ----------
    starts_m : sequence of float, shape (n,)
        Increasing locations [m]; ``decelerations_mps2[i]`` holds from ``starts_m[i]`` to the
        next start. The first value also holds before ``starts_m[0]``, the last after the end.
    decelerations_mps2 : sequence of float, shape (n,)
        Decelerations [m/s²], each > 0.

    Raises
    ------
    BrakingCapabilityError
        If a deceleration is not positive: the train could not stop on that stretch.
    """

    __slots__ = ("starts_m", "values_mps2")

    def __init__(self, starts_m: Sequence[float], decelerations_mps2: Sequence[float]) -> None:
        if len(starts_m) != len(decelerations_mps2) or not starts_m:
            raise EtcsInputError("a deceleration profile needs as many starts as values, ≥ 1")
        if any(b <= a for a, b in zip(starts_m, starts_m[1:], strict=False)):
            raise EtcsInputError("deceleration profile starts must increase")
        for start_m, value in zip(starts_m, decelerations_mps2, strict=True):
            if not (math.isfinite(value) and value > 0.0):
                raise BrakingCapabilityError(
                    f"deceleration {value:.3f} m/s² from {start_m:.1f} m: the train cannot stop"
                )
        self.starts_m = tuple(float(s) for s in starts_m)
        self.values_mps2 = tuple(float(v) for v in decelerations_mps2)

    @classmethod
    def uniform(cls, deceleration_mps2: float) -> DecelerationProfile:
        """The same deceleration everywhere (level track, or a constant gradient)."""
        return cls([0.0], [deceleration_mps2])

    @classmethod
    def from_gradients(
        cls,
        steps: Sequence[GradientStep],
        *,
        brake_deceleration_mps2: float,
        fixed: FixedValues,
        rotating_mass_percent: float | None = None,
    ) -> DecelerationProfile:
        """A_brake + A_gradient over gradient steps that already apply to the front end."""
        if not steps:
            raise EtcsInputError("no gradient steps")
        values = [
            brake_deceleration_mps2
            + gradient_acceleration_mps2(
                gradient, fixed=fixed, rotating_mass_percent=rotating_mass_percent
            )
            for _, _, gradient in steps
        ]
        return cls([low for low, _, _ in steps], values)

    @classmethod
    def from_track_map(
        cls,
        track_map: TrackMap,
        *,
        start_m: float,
        end_m: float,
        brake_deceleration_mps2: float,
        train_length_m: float,
        fixed: FixedValues,
        rotating_mass_percent: float | None = None,
    ) -> DecelerationProfile:
        """A_brake + A_gradient for front-end locations in ``[start_m, end_m)`` [m].

        The gradient is read from ``train_length_m`` behind ``start_m`` on, so that the lowest
        gradient under the train is known from the window's start.
        """
        raw = gradient_steps(track_map, start_m - train_length_m, end_m)
        under_train = [
            (max(low, start_m), high, gradient)
            for low, high, gradient in lowest_gradient_under_train(raw, train_length_m)
            if high > start_m
        ]
        return cls.from_gradients(
            under_train,
            brake_deceleration_mps2=brake_deceleration_mps2,
            fixed=fixed,
            rotating_mass_percent=rotating_mass_percent,
        )

    def at(self, location_m: float) -> float:
        """The deceleration [m/s²] at a front-end location [m]."""
        index = max(bisect.bisect_right(self.starts_m, location_m) - 1, 0)
        return self.values_mps2[index]

    def __repr__(self) -> str:
        return f"DecelerationProfile({list(self.starts_m)!r}, {list(self.values_mps2)!r})"
