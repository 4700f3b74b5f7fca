"""The ADF supervisory controller: every transition, and the bumpless hand-over."""

from __future__ import annotations

import pytest

from onboard.adf.supervisor import ModeRequest, SupervisoryController
from protocol.messages import ScState

DT = 0.1
U_RANGE_N = 45_000.0


def _run(
    sc: SupervisoryController, seconds: float, start_s: float, rd: float, ad: float
) -> list[float]:
    forces = []
    for k in range(round(seconds / DT)):
        force = sc.step(DT, start_s + k * DT, remote_force_n=rd, autonomous_force_n=ad)
        forces.append(0.0 if force is None else force)
    return forces


@pytest.mark.parametrize(
    ("start", "mode", "expected"),
    [
        (ScState.OFF, ModeRequest.REMOTE, ScState.RD),
        (ScState.OFF, ModeRequest.AUTONOMOUS, ScState.AD),
        (ScState.OFF, ModeRequest.OFF, ScState.OFF),
        (ScState.RD, ModeRequest.AUTONOMOUS, ScState.HRD2AD),
        (ScState.RD, ModeRequest.REMOTE, ScState.RD),
        (ScState.RD, ModeRequest.OFF, ScState.OFF),
        (ScState.AD, ModeRequest.REMOTE, ScState.HAD2RD),
        (ScState.AD, ModeRequest.AUTONOMOUS, ScState.AD),
        (ScState.AD, ModeRequest.OFF, ScState.OFF),
        (ScState.HRD2AD, ModeRequest.REMOTE, ScState.HAD2RD),
        (ScState.HRD2AD, ModeRequest.OFF, ScState.OFF),
        (ScState.HAD2RD, ModeRequest.AUTONOMOUS, ScState.HRD2AD),
        (ScState.HAD2RD, ModeRequest.OFF, ScState.OFF),
    ],
)
def test_transitions(start: ScState, mode: ModeRequest, expected: ScState) -> None:
    sc = _in_state(start)
    sc.acknowledge_replan()
    sc.request(mode, 100.0)
    assert sc.state is expected
    assert sc.replan_requested is (expected is not start)


def _in_state(state: ScState) -> SupervisoryController:
    sc = SupervisoryController()
    if state is ScState.RD:
        sc.request(ModeRequest.REMOTE, 0.0)
    elif state is ScState.AD:
        sc.request(ModeRequest.AUTONOMOUS, 0.0)
    elif state is ScState.HRD2AD:
        sc.request(ModeRequest.REMOTE, 0.0)
        sc.request(ModeRequest.AUTONOMOUS, 0.0)
    elif state is ScState.HAD2RD:
        sc.request(ModeRequest.AUTONOMOUS, 0.0)
        sc.request(ModeRequest.REMOTE, 0.0)
    assert sc.state is state
    return sc


def test_hand_overs_complete_in_bounded_time() -> None:
    sc = _in_state(ScState.RD)
    sc.request(ModeRequest.AUTONOMOUS, 0.0)
    _run(sc, sc.handover_s + DT, 0.0, rd=1000.0, ad=3000.0)
    assert sc.state is ScState.AD
    sc.request(ModeRequest.REMOTE, 10.0)
    _run(sc, sc.handover_s + DT, 10.0, rd=1000.0, ad=3000.0)
    assert sc.state is ScState.RD
    assert [t.target for t in sc.transitions] == [
        ScState.RD,
        ScState.HRD2AD,
        ScState.AD,
        ScState.HAD2RD,
        ScState.RD,
    ]


def test_the_applied_force_moves_without_jumps() -> None:
    """Controllers that disagree by 8 kN: each step changes u by at most 2 % of its range."""
    sc = _in_state(ScState.RD)
    before = _run(sc, 1.0, 0.0, rd=2_000.0, ad=10_000.0)
    sc.request(ModeRequest.AUTONOMOUS, 1.0)
    during = _run(sc, 3.0, 1.0, rd=2_000.0, ad=10_000.0)
    sc.request(ModeRequest.REMOTE, 4.0)
    back = _run(sc, 1.0, 4.0, rd=2_000.0, ad=10_000.0)
    sc.request(ModeRequest.AUTONOMOUS, 5.0)  # turned round mid-way
    again = _run(sc, 3.0, 5.0, rd=2_000.0, ad=10_000.0)
    forces = before + during + back + again
    jumps = [abs(b - a) for a, b in zip(forces, forces[1:], strict=False)]
    assert max(jumps) <= 0.02 * U_RANGE_N
    assert forces[0] == 2_000.0
    assert forces[-1] == 10_000.0


def test_off_holds_the_vehicle() -> None:
    sc = SupervisoryController()
    assert sc.step(DT, 0.0, remote_force_n=5.0, autonomous_force_n=5.0) is None
    assert not sc.needs_remote
    assert not sc.needs_autonomous


def test_which_controllers_run() -> None:
    assert _in_state(ScState.RD).needs_remote
    assert not _in_state(ScState.RD).needs_autonomous
    assert _in_state(ScState.AD).needs_autonomous
    assert not _in_state(ScState.AD).needs_remote
    for state in (ScState.HRD2AD, ScState.HAD2RD):
        sc = _in_state(state)
        assert sc.needs_remote
        assert sc.needs_autonomous


def test_bad_handover_time() -> None:
    with pytest.raises(ValueError, match="positive duration"):
        SupervisoryController(handover_s=0.0)
