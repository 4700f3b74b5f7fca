"""Task C: EB by de-energising the valves, rearm only when safe and confirmed, ETCS relay."""

from __future__ import annotations

from dataclasses import dataclass, field

from onboard.vc import (
    BrakeState,
    DecayReason,
    EbCondition,
    EtcsState,
    Mailbox,
    SupervisionStatus,
    TaskC,
    VcConfig,
    VcEventKind,
)
from tests.onboard.vc.helpers import supervision


@dataclass
class Rig:
    task: TaskC
    inbox: Mailbox[SupervisionStatus]
    valves: list[tuple[bool, float]] = field(default_factory=list)
    relay: list[tuple[bool, float]] = field(default_factory=list)

    def step(self, time_s: float, **changes: object) -> BrakeState:
        self.inbox.post(supervision(time_s, **changes))
        self.task.step(time_s)
        return self.task.brake.state


def _rig(*, etcs_inserted: bool = True) -> Rig:
    inbox = Mailbox[SupervisionStatus]()
    valves: list[tuple[bool, float]] = []
    relay: list[tuple[bool, float]] = []
    task = TaskC(
        VcConfig(),
        supervision=inbox,
        command_valves=lambda energised, t: valves.append((energised, t)),
        command_relay=lambda inserted, t: relay.append((inserted, t)),
        etcs_inserted=etcs_inserted,
    )
    return Rig(task, inbox, valves, relay)


def _released(rig: Rig) -> None:
    """Power-up to RELEASED: standstill, rearm confirmed (number 1), EB input released."""
    assert rig.step(0.0, standstill=True) is BrakeState.STANDSTILL
    assert rig.step(0.002, standstill=True, eb_rearm_confirmed_number=1) is BrakeState.REARMING
    assert rig.step(0.004, standstill=True, eb_rearm_confirmed_number=1, eb_released=True) is (
        BrakeState.RELEASED
    )


def test_powers_up_braking_with_the_valves_de_energised() -> None:
    rig = _rig()
    assert rig.step(0.0) is BrakeState.BRAKING
    assert rig.valves == [(False, 0.0)]


def test_eb_flag_de_energises_the_valves_in_the_same_cycle() -> None:
    rig = _rig()
    _released(rig)
    assert rig.valves[-1] == (True, 0.004)
    assert rig.step(0.006, eb_flag=True) is BrakeState.BRAKING
    assert rig.valves[-1] == (False, 0.006)
    assert [e.kind for e in rig.task.events][-1] is VcEventKind.EB_COMMANDED


def test_rearm_refused_while_not_at_standstill() -> None:
    rig = _rig()
    assert rig.step(0.0, eb_rearm_confirmed_number=3) is BrakeState.BRAKING
    assert rig.valves[-1] == (False, 0.0)
    refused = [e for e in rig.task.events if e.kind is VcEventKind.REQUEST_REFUSED]
    assert [e.detail for e in refused] == ["rearm #3: not at standstill, or not safe"]
    assert rig.step(0.002, standstill=True, eb_rearm_confirmed_number=3) is BrakeState.STANDSTILL
    # Standstill lost before the rearm: refused again, still no rearm.
    assert rig.step(0.004, eb_rearm_confirmed_number=3) is BrakeState.STANDSTILL
    assert rig.step(0.006, standstill=True, eb_rearm_confirmed_number=3) is BrakeState.REARMING
    assert rig.valves[-1] == (True, 0.006)


def test_rearm_refused_while_a_hazard_holds_or_the_flag_is_up() -> None:
    rig = _rig()
    rig.step(0.0, standstill=True)
    hazard = frozenset({EbCondition.ODOMETRY_NOT_EFFICIENT})
    assert rig.step(
        0.002, standstill=True, eb_rearm_confirmed_number=1, live_conditions=hazard
    ) is (BrakeState.STANDSTILL)
    assert rig.step(0.004, standstill=True, eb_rearm_confirmed_number=1, eb_flag=True) is (
        BrakeState.STANDSTILL
    )
    assert rig.step(0.006, standstill=True, eb_rearm_confirmed_number=1) is BrakeState.REARMING


def test_a_confirmation_is_acted_on_once() -> None:
    rig = _rig()
    rig.step(0.0, standstill=True)
    rig.step(0.002, standstill=True, eb_rearm_confirmed_number=1)
    assert rig.step(0.004, standstill=True, eb_rearm_confirmed_number=1, eb_flag=True) is (
        BrakeState.BRAKING
    )
    assert rig.step(0.006, standstill=True, eb_rearm_confirmed_number=1) is BrakeState.STANDSTILL
    assert rig.step(0.008, standstill=True, eb_rearm_confirmed_number=1) is BrakeState.STANDSTILL
    assert rig.step(0.010, standstill=True, eb_rearm_confirmed_number=2) is BrakeState.REARMING


def test_rearm_not_applied_within_its_timeout_is_system_decay() -> None:
    rig = _rig()
    rig.step(0.0, standstill=True)
    rig.step(0.002, standstill=True, eb_rearm_confirmed_number=1)
    assert rig.step(2.002, standstill=True, eb_rearm_confirmed_number=1) is BrakeState.REARMING
    assert rig.step(2.004, standstill=True, eb_rearm_confirmed_number=1) is BrakeState.DECAYED
    assert rig.valves[-1] == (False, 2.004)
    status = rig.task.status.read()
    assert status is not None
    assert status.decay_reasons == (DecayReason.EB_REARM_NOT_APPLIED,)


def test_system_decay_from_b_holds_the_eb_for_good() -> None:
    rig = _rig()
    _released(rig)
    assert rig.step(0.006, system_decay=True, eb_flag=True, standstill=True) is BrakeState.DECAYED
    assert rig.step(0.008, standstill=True, eb_rearm_confirmed_number=9) is BrakeState.DECAYED
    assert rig.valves[-1] == (False, 0.008)


def test_etcs_isolation_with_re_read_verification() -> None:
    rig = _rig()
    rig.step(0.0, etcs_isolation_confirmed_number=1)
    assert rig.task.etcs.state is EtcsState.INSERTED  # moving: refused
    rig.step(0.002, standstill=True, etcs_isolation_confirmed_number=1)
    assert rig.task.etcs.state is EtcsState.ISOLATING
    assert rig.relay == [(False, 0.002)]
    rig.step(0.1, standstill=True, etcs_isolation_confirmed_number=1)
    assert rig.task.etcs.state is EtcsState.ISOLATING
    rig.step(0.102, standstill=True, etcs_isolated=True)
    assert rig.task.etcs.state is EtcsState.ISOLATED


def test_a_relay_that_does_not_actuate_is_system_decay() -> None:
    rig = _rig(etcs_inserted=False)
    rig.step(0.0, standstill=True, etcs_isolated=True, etcs_insertion_confirmed_number=1)
    assert rig.task.etcs.state is EtcsState.INSERTING
    assert rig.relay == [(True, 0.0)]
    rig.step(0.1, standstill=True, etcs_isolated=True)
    assert rig.task.etcs.state is EtcsState.INSERTING
    rig.step(0.102, standstill=True, etcs_isolated=True)
    assert rig.task.etcs.state is EtcsState.FAILED
    assert rig.task.brake.state is BrakeState.DECAYED
    status = rig.task.status.read()
    assert status is not None
    assert status.decay_reasons == (DecayReason.ETCS_INSERTION_NOT_ACTUATED,)
