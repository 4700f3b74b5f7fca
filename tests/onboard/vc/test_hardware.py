"""Emulated I/O: EB valves and brake pipe, the ETCS radio relay, the tachometer board."""

from __future__ import annotations

import pytest
from numpy.testing import assert_allclose

from onboard.vc import (
    FULL_EB_DELAY_S,
    EmergencyBrakeValves,
    PipeFault,
    RadioRelay,
    RelayFault,
    TachometerBoard,
    TachometerFault,
    TachometerFaultMode,
    TachometerFrame,
    VcConfig,
    VcInputError,
)

MPP = VcConfig().metres_per_pulse


def test_power_up_with_the_eb_applied_then_rearm_and_release() -> None:
    valves = EmergencyBrakeValves(recharge_s=1.0)
    assert not valves.energised
    assert valves.brake_effort(0.0) == 1.0
    assert not valves.eb_released(0.0)
    valves.command(True, 0.0)
    assert not valves.eb_released(0.94)
    assert valves.eb_released(0.96)
    assert_allclose(valves.pressure_fraction(0.5), 0.5, atol=1e-12)


def test_full_eb_450_ms_after_de_energising() -> None:
    assert FULL_EB_DELAY_S == 0.450
    valves = EmergencyBrakeValves(energised=True)
    valves.command(False, 2.0)
    (command,) = valves.commands
    assert valves.full_emergency_brake_s(command) == pytest.approx(2.45)
    assert_allclose(valves.brake_effort(2.225), 0.5, atol=1e-12)
    assert valves.brake_effort(2.45) == pytest.approx(1.0)
    assert not valves.eb_released(2.0)


def test_pipe_venting_time_is_configurable_and_partial_pressure_vents_sooner() -> None:
    valves = EmergencyBrakeValves(venting_s=0.3, recharge_s=1.0)
    valves.command(True, 0.0)
    valves.command(False, 0.5)
    command = valves.commands[-1]
    assert command.pressure_fraction == pytest.approx(0.5)
    assert valves.full_emergency_brake_s(command) == pytest.approx(0.65)


def test_a_pipe_fault_keeps_the_rearm_from_recharging() -> None:
    valves = EmergencyBrakeValves(faults=(PipeFault(start_s=0.0, end_s=5.0),))
    valves.command(True, 1.0)
    assert valves.energised
    assert valves.pressure_fraction(3.0) == 0.0
    assert not valves.eb_released(3.0)


def test_relay_switches_after_its_delay_and_reads_back() -> None:
    relay = RadioRelay(switching_delay_s=0.02)
    relay.command(False, 1.0)
    assert relay.inserted(1.019)
    assert not relay.inserted(1.02)
    assert relay.commands == [(1.0, False)]


def test_a_relay_fault_does_not_actuate_and_the_re_read_shows_it() -> None:
    relay = RadioRelay(faults=(RelayFault(start_s=0.0),))
    relay.command(False, 1.0)
    assert not relay.commanded_inserted
    assert relay.inserted(2.0)


def _frames(
    board: TachometerBoard, speed_mps: float, until_s: float
) -> list[tuple[float, TachometerFrame]]:
    out = []
    for k in range(round(until_s / 0.002) + 1):
        now_s = k * 0.002
        frame = board.poll(now_s, speed_mps * now_s)
        if frame is not None:
            out.append((now_s, frame))
    return out


def test_board_sends_a_frame_every_80_ms_counting_pulses() -> None:
    board = TachometerBoard(metres_per_pulse=MPP)
    frames = _frames(board, 5.0, 1.0)
    assert [round(t, 3) for t, _ in frames] == [round(0.08 * k, 3) for k in range(13)]
    last = frames[-1][1]
    assert last.frame_number == 12
    assert abs(last.pulses_a - 5.0 * 0.96 / MPP) <= 1
    assert abs(last.pulses_a - last.pulses_b) <= 1


@pytest.mark.parametrize("mode", list(TachometerFaultMode))
def test_board_fault_modes(mode: TachometerFaultMode) -> None:
    board = TachometerBoard(
        metres_per_pulse=MPP, faults=(TachometerFault(mode=mode, start_s=0.3, end_s=0.6),)
    )
    frames = _frames(board, 5.0, 1.0)
    window = [f for t, f in frames if 0.3 <= t < 0.6]
    before = [f for t, f in frames if t < 0.3]
    if mode is TachometerFaultMode.SILENT:
        assert window == []
        assert len(frames) == 9
    elif mode is TachometerFaultMode.FROZEN:
        assert set(window) == {before[-1]}
    else:
        # Channel B's count jumps by 8 to 16 pulses a frame against channel A's.
        pairs = zip([before[-1], *window], window, strict=False)
        jumps = [(b.pulses_b - a.pulses_b) - (b.pulses_a - a.pulses_a) for a, b in pairs]
        assert all(7 <= abs(j) <= 17 for j in jumps)


def test_fault_windows_must_make_sense() -> None:
    with pytest.raises(VcInputError):
        PipeFault(start_s=2.0, end_s=1.0)
    with pytest.raises(VcInputError):
        EmergencyBrakeValves(venting_s=0.0)
