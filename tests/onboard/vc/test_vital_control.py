"""VitalControl on the executive: B > C > A, the requests Task A composes, the outputs."""

from __future__ import annotations

import importlib
import pkgutil

import pytest

import onboard.vc
from deploy.bench.vc_responder import AtoObResponder
from onboard.etcs.balises import TelegramHeader
from onboard.runtime import Executive, SimClock
from onboard.runtime.clock import NS_PER_S
from onboard.vc import (
    BrakeState,
    Delivery,
    Notification,
    Section,
    TachometerBoard,
    TaskAState,
    VcConfig,
    VcError,
    VcHardware,
    VcInputError,
    VcRequest,
    VitalControl,
)

MS = 1_000_000


class StandingTrain:
    """A train at rest: the odometry board's frames every 80 ms, and nothing else."""

    def __init__(self, hardware: VcHardware) -> None:
        self.hardware = hardware
        self.board = TachometerBoard(metres_per_pulse=VcConfig().metres_per_pulse)

    def step_ns(self, release_ns: int) -> None:
        now_s = release_ns / NS_PER_S
        frame = self.board.poll(now_s, 0.0)
        if frame is not None:
            self.hardware.tachometer_frames.put(Delivery(frame, now_s))


def _bench(
    *, event_driven: bool = False, **responder: object
) -> tuple[Executive, VitalControl, AtoObResponder]:
    """The VC between a standing train and an ATO-OB double; by default every cycle a full one
    in separate tasks (``event_driven``: B and C as the sleeping ``vc.tick``)."""
    hardware = VcHardware.emulated()
    vc = VitalControl(hardware)
    double = AtoObResponder(hardware.request_link, hardware.response_link, **responder)  # type: ignore[arg-type]
    executive = Executive(SimClock(), record_trace=True)
    executive.add_task("train", StandingTrain(hardware).step_ns, period_s=0.002, priority=40)
    vc.register(executive, event_driven=event_driven)
    executive.add_task("ato_ob", double.step_ns, period_s=0.002, priority=0)
    return executive, vc, double


def test_tasks_run_b_then_c_then_a_with_the_seeds_periods() -> None:
    executive, _, _ = _bench()
    assert {
        n: (t.period_ns, t.priority) for n, t in executive.tasks.items() if n.startswith("vc.")
    } == {
        "vc.B": (2 * MS, 30),
        "vc.C": (2 * MS, 20),
        "vc.A": (40 * MS, 10),
    }
    executive.run_until(40 * MS)
    assert executive.trace is not None
    at_zero = [name for t, name in executive.trace if t == 0]
    assert at_zero == ["train", "vc.B", "vc.C", "vc.A", "ato_ob"]
    assert [name for t, name in executive.trace if t == 2 * MS] == [
        "train",
        "vc.B",
        "vc.C",
        "ato_ob",
    ]


def test_in_lockstep_b_and_c_are_one_task_that_sleeps_between_inputs() -> None:
    executive, vc, _ = _bench(event_driven=True)
    assert {
        n: (t.period_ns, t.priority) for n, t in executive.tasks.items() if n.startswith("vc.")
    } == {"vc.tick": (2 * MS, 30), "vc.A": (40 * MS, 10)}
    executive.run_until(1000 * MS)
    assert executive.trace is not None
    assert [name for t, name in executive.trace if t == 0] == ["train", "vc.tick", "vc.A", "ato_ob"]
    ticks = executive.stats["vc.tick"].releases
    assert vc.tick is not None
    # An instant is released or slept through (those since the last release are counted at the
    # next), and most are slept through.
    assert 450 < ticks + vc.tick.slept <= 501
    assert ticks < 250
    assert vc.task_b.quiet.skipped >= vc.tick.slept


def _requests(executive: Executive, vc: VitalControl, until_s: float) -> list[VcRequest]:
    requests = []
    for k in range(round(until_s / 0.04) + 1):
        executive.run_until(k * 40 * MS)
        assert vc.task_a.last_request is not None
        requests.append(vc.task_a.last_request)
    return requests


def test_pulsed_sections_take_a_new_number_in_every_request() -> None:
    executive, vc, _ = _bench()
    requests = _requests(executive, vc, 1.0)
    for section in (Section.ATO_VITALITY, Section.EB_RELEASE_CONFIRMATION):
        numbers = [r.section(section).sequence_number for r in requests]
        assert numbers == [(k + 1) % 256 for k in range(len(requests))]
        assert all(r.section(section).request_flag for r in requests)


def test_a_standing_flag_keeps_its_number_until_settled() -> None:
    executive, vc, _ = _bench()
    requests = _requests(executive, vc, 5.5)
    vigilance = [r.section(Section.OPERATOR_VIGILANCE) for r in requests]
    raised = [
        k
        for k in range(1, len(vigilance))
        if vigilance[k].request_flag and not vigilance[k - 1].request_flag
    ]
    assert vigilance[0].request_flag
    assert raised == [125]
    up = [v.sequence_number for v in vigilance if v.request_flag]
    assert set(up) == {1, 2}
    # Confirmed by the operator 0.3 s after the request, seen by Task A at its next release.
    assert sum(v.request_flag for v in vigilance[:20]) == 9


def test_power_up_asks_the_rearm_at_standstill_then_releases_the_eb() -> None:
    executive, vc, _ = _bench()
    executive.run_until(240 * MS)
    assert vc.outputs.standstill
    assert vc.outputs.task_a_state is TaskAState.REARM_PENDING
    request = vc.task_a.last_request
    assert request is not None
    assert request.section(Section.EB_REARM_CONFIRMATION).request_flag
    assert Notification.REARM_REQUESTED in request.notifications
    assert request.section(Section.ETCS_ISOLATION_CONFIRMATION).request_flag
    assert vc.outputs.eb_commanded
    executive.run_until(round(1.6 * NS_PER_S))
    outputs = vc.outputs
    assert not outputs.eb_commanded
    assert outputs.brake_state is BrakeState.RELEASED
    assert outputs.task_a_state is TaskAState.SUPERVISING
    assert not outputs.system_decay
    assert not outputs.etcs_isolated
    assert outputs.speed_mps == 0.0


def test_the_last_balise_header_is_forwarded_to_the_ato_ob() -> None:
    executive, vc, double = _bench()
    executive.run_until(100 * MS)
    vc.hardware.balise_telegrams.put(Delivery(TelegramHeader(nid_bg=7, q_link=1), 0.1))
    executive.run_until(200 * MS)
    assert double.last_request is not None
    assert double.last_request.last_balise_header is not None
    assert double.last_request.last_balise_header.nid_bg == 7
    assert double.balise_headers_seen == [7]


def test_without_the_operator_the_eb_stays_applied() -> None:
    executive, vc, _ = _bench(auto_confirm_rearm=False)
    executive.run_until(3 * NS_PER_S)
    assert vc.outputs.eb_commanded
    assert vc.outputs.brake_state is BrakeState.STANDSTILL


def test_config_is_checked() -> None:
    with pytest.raises(VcInputError):
        VcConfig(task_b_period_s=0.0)
    with pytest.raises(VcInputError):
        VcConfig(exchange_window_s=0.03)
    assert issubclass(VcInputError, ValueError)
    assert issubclass(VcInputError, VcError)


def test_all_is_complete_and_reexports_the_modules() -> None:
    exported = set(onboard.vc.__all__)
    assert all(hasattr(onboard.vc, name) for name in exported)
    for info in pkgutil.iter_modules(onboard.vc.__path__, prefix="onboard.vc."):
        module = importlib.import_module(info.name)
        assert set(module.__all__) <= exported, info.name
