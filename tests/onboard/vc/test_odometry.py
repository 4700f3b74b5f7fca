"""Task B's tachometer odometry: speed, position, standstill, efficiency (seed 004, S6)."""

from __future__ import annotations

import pytest
from numpy.testing import assert_allclose

from onboard.vc import (
    Delivery,
    OdometryEstimate,
    TachometerBoard,
    TachometerFault,
    TachometerFaultMode,
    TachometerOdometry,
    VcConfig,
)

CONFIG = VcConfig()
RESOLUTION_MPS = CONFIG.metres_per_pulse / CONFIG.tachometer_period_s
"""One pulse per frame interval."""


def _run(
    speed_mps: float, until_s: float, *faults: TachometerFault
) -> list[tuple[float, OdometryEstimate]]:
    board = TachometerBoard(metres_per_pulse=CONFIG.metres_per_pulse, faults=faults)
    odometry = TachometerOdometry(CONFIG)
    out = []
    for k in range(round(until_s / 0.002) + 1):
        now_s = k * 0.002
        frame = board.poll(now_s, speed_mps * now_s)
        frames = [Delivery(frame, now_s)] if frame is not None else []
        out.append((now_s, odometry.update(now_s, frames)))
    return out


def _at(run: list[tuple[float, OdometryEstimate]], time_s: float) -> OdometryEstimate:
    return next(e for t, e in run if t >= time_s - 1e-9)


def test_speed_and_position_within_a_pulse() -> None:
    run = _run(8.0, 2.0)
    estimate = _at(run, 2.0)
    assert estimate.efficient
    assert not estimate.standstill
    assert estimate.speed_mps is not None
    assert estimate.position_m is not None
    assert_allclose(estimate.speed_mps, 8.0, atol=RESOLUTION_MPS)
    assert_allclose(estimate.position_m, 16.0, atol=CONFIG.metres_per_pulse)


def test_efficient_and_standstill_after_three_frames_from_power_up() -> None:
    run = _run(0.0, 0.5)
    assert not _at(run, 0.238).efficient
    estimate = _at(run, 0.24)
    assert estimate.efficient
    assert estimate.standstill
    assert estimate.speed_mps == 0.0


@pytest.mark.parametrize(
    ("mode", "evident_s", "recovered_s"),
    [
        # The first repeated frame. The first fresh one (1.36 s) jumps five numbers: it is only
        # a new reference; three good frames follow.
        (TachometerFaultMode.FROZEN, 1.04, 1.60),
        # The first noisy frame; the frames from 1.36 s on are good.
        (TachometerFaultMode.NOISY, 1.04, 1.52),
        # The last frame (0.96 s) + 96 ms; then as FROZEN.
        (TachometerFaultMode.SILENT, 1.056, 1.60),
    ],
)
def test_each_board_fault_makes_the_odometry_not_efficient(
    mode: TachometerFaultMode, evident_s: float, recovered_s: float
) -> None:
    run = _run(8.0, 2.0, TachometerFault(mode=mode, start_s=1.0, end_s=1.3))
    assert _at(run, evident_s - 0.002).efficient
    bad = _at(run, evident_s + 0.002)
    assert not bad.efficient
    assert bad.speed_mps is None
    assert not bad.standstill
    assert bad.not_efficient_since_s == pytest.approx(evident_s)
    assert not _at(run, recovered_s - 0.002).efficient
    assert _at(run, recovered_s).efficient


def test_a_jump_in_the_frame_numbers_is_not_plausible() -> None:
    odometry = TachometerOdometry(CONFIG)
    from onboard.vc import TachometerFrame

    for k, number in enumerate([0, 1, 2, 3, 9]):
        estimate = odometry.update(0.08 * k, [Delivery(TachometerFrame(number, 0, 0), 0.08 * k)])
        if k == 3:
            assert estimate.efficient
    assert not estimate.efficient
