"""Two replicas in 2-out-of-2 and the watchdog: either EB brakes, disagreement and silence trip."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from deploy.bench.vc_responder import AtoObResponder, ResponderFault, ResponderFaultKind
from onboard.runtime import Executive, SimClock
from onboard.runtime.clock import NS_PER_S
from onboard.vc import (
    Delivery,
    EmergencyBrakeValves,
    TachometerBoard,
    TachometerFault,
    TachometerFaultMode,
    VcConfig,
    VcHardware,
    VcInputError,
    VitalControl,
)
from onboard.vc.redundancy import (
    PairEventKind,
    RedundancyConfig,
    ReplicaFault,
    ReplicaFaultKind,
    ReplicaView,
    TwoOutOfTwo,
    Watchdog,
)

POWER_UP_REARM_S = 2.0
"""By then the power-up rearm is done (≈ 1.5 s) and the valves energised."""


class StandingTrainForTwo:
    """A train at rest feeding each replica's own tachometer board (one may be faulty)."""

    def __init__(
        self, hardware: Sequence[VcHardware], faults: Sequence[Sequence[TachometerFault]]
    ) -> None:
        self.hardware = hardware
        metres_per_pulse = VcConfig().metres_per_pulse
        self.boards = [TachometerBoard(metres_per_pulse=metres_per_pulse, faults=f) for f in faults]

    def step_ns(self, release_ns: int) -> None:
        now_s = release_ns / NS_PER_S
        for board, ports in zip(self.boards, self.hardware, strict=True):
            frame = board.poll(now_s, 0.0)
            if frame is not None:
                ports.tachometer_frames.put(Delivery(frame, now_s))


def _pair(
    *,
    responder_faults: tuple[Sequence[ResponderFault], Sequence[ResponderFault]] = ((), ()),
    tachometer_faults: tuple[Sequence[TachometerFault], Sequence[TachometerFault]] = ((), ()),
    replica_faults: Sequence[ReplicaFault] = (),
    config: RedundancyConfig | None = None,
) -> tuple[Executive, TwoOutOfTwo]:
    hardware = (VcHardware.emulated(), VcHardware.emulated())
    pair = TwoOutOfTwo(
        (VitalControl(hardware[0]), VitalControl(hardware[1])),
        valves=EmergencyBrakeValves(),
        faults=replica_faults,
        config=config,
    )
    executive = Executive(SimClock())
    train = StandingTrainForTwo(hardware, tachometer_faults)
    executive.add_task("train", train.step_ns, period_s=0.002, priority=40)
    pair.register(executive)
    for index, ports in enumerate(hardware):
        double = AtoObResponder(
            ports.request_link, ports.response_link, faults=responder_faults[index]
        )
        executive.add_task(f"ato_ob{index}", double.step_ns, period_s=0.002, priority=0)
    return executive, pair


def test_a_healthy_pair_never_brakes_in_a_nominal_run() -> None:
    executive, pair = _pair()
    executive.run_for(POWER_UP_REARM_S)
    assert not pair.eb_commanded
    executive.run_for(12.0)  # two vigilance requests and their confirmations
    assert not pair.eb_commanded
    assert not pair.tripped
    assert pair.events == []
    assert [c.energised for c in pair.valves.commands] == [True]


@pytest.mark.parametrize("faulty", [0, 1])
def test_either_replica_demanding_eb_brakes_the_vehicle(faulty: int) -> None:
    fail = ResponderFault(kind=ResponderFaultKind.STATUS_FAIL, start_s=3.0)
    faults: list[tuple[ResponderFault, ...]] = [(), ()]
    faults[faulty] = (fail,)
    executive, pair = _pair(responder_faults=(faults[0], faults[1]))
    executive.run_for(POWER_UP_REARM_S)
    assert not pair.eb_commanded
    executive.run_for(2.0)
    assert pair.eb_commanded
    assert pair.replicas[faulty].outputs.eb_commanded
    assert not pair.replicas[1 - faulty].outputs.eb_commanded
    replica_eb = [e for e in pair.events if e.kind is PairEventKind.REPLICA_EB]
    assert [e.replica for e in replica_eb] == [faulty]
    # The vehicle brakes in the tick the replica opened its contact.
    assert pair.valves.commands[-1].time_s == pytest.approx(replica_eb[0].time_s, abs=1e-9)


def test_a_disagreement_longer_than_the_tolerance_brakes() -> None:
    # Replica 1's own tachometer board goes noisy: with ETCS inserted it does not demand EB
    # (ETCS supervises), but it no longer sees odometry as efficient: the replicas disagree.
    noisy = TachometerFault(mode=TachometerFaultMode.NOISY, start_s=3.0)
    executive, pair = _pair(tachometer_faults=((), (noisy,)))
    executive.run_for(POWER_UP_REARM_S)
    assert not pair.eb_commanded
    executive.run_for(2.0)
    assert pair.tripped_by is PairEventKind.DISAGREEMENT
    assert pair.eb_commanded
    assert not any(replica.outputs.eb_commanded for replica in pair.replicas)
    (trip,) = [e for e in pair.events if e.kind is PairEventKind.DISAGREEMENT]
    assert "odometry_efficient" in trip.detail
    assert pair.disagreeing_since_s is not None
    assert trip.time_s - pair.disagreeing_since_s == pytest.approx(0.012, abs=1e-6)
    executive.run_for(1.0)
    assert pair.eb_commanded  # latched until a restart


def test_a_disagreement_within_the_tolerance_does_not_brake() -> None:
    noisy = TachometerFault(mode=TachometerFaultMode.NOISY, start_s=3.0)
    executive, pair = _pair(
        tachometer_faults=((), (noisy,)), config=RedundancyConfig(disagreement_tolerance_s=10.0)
    )
    executive.run_for(5.0)
    assert pair.disagreeing_since_s is not None
    assert pair.tripped_by is None
    assert not pair.eb_commanded


def test_watchdog_expiry_brakes_when_a_replica_stops_answering() -> None:
    halt = ReplicaFault(kind=ReplicaFaultKind.HALT, replica=0, start_s=3.0)
    executive, pair = _pair(replica_faults=(halt,))
    executive.run_for(POWER_UP_REARM_S)
    assert not pair.eb_commanded
    executive.run_for(2.0)
    assert pair.tripped_by is PairEventKind.WATCHDOG_EXPIRED
    (trip,) = [e for e in pair.events if e.kind is PairEventKind.WATCHDOG_EXPIRED]
    assert trip.replica == 0
    # Last kick at 2.998 s; expired at the first check more than 10 ms later.
    assert trip.time_s == pytest.approx(3.010, abs=1e-6)
    assert pair.valves.commands[-1].time_s == pytest.approx(3.010, abs=1e-6)
    assert not pair.valves.commands[-1].energised
    # The halted replica still shows its contact closed: only the watchdog cut the power.
    assert pair.replicas[0].hardware.valves.energised


def test_watchdog_expires_only_past_its_timeout_and_stays_expired() -> None:
    watchdog = Watchdog(0.010, start_s=0.0)
    watchdog.kick(1.0)
    assert not watchdog.check(1.010)
    assert watchdog.check(1.012)
    watchdog.kick(1.014)
    assert watchdog.check(1.014)
    assert watchdog.expired_at_s == pytest.approx(1.012)


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(VcInputError):
        Watchdog(0.0)
    with pytest.raises(VcInputError):
        RedundancyConfig(watchdog_timeout_s=-1.0)
    with pytest.raises(VcInputError):
        ReplicaFault(kind=ReplicaFaultKind.HALT, replica=2, start_s=0.0)


def test_the_vote_key_is_the_replica_view_of_the_outputs() -> None:
    """The voter compares cheap keys every 2 ms; a key must say exactly what the view says, in
    a nominal stretch and through a disagreement (replica 1's board goes noisy)."""
    noisy = TachometerFault(mode=TachometerFaultMode.NOISY, start_s=3.0)
    executive, pair = _pair(tachometer_faults=((), (noisy,)))
    keys_differed = False
    for _ in range(500):  # 5 s: the board goes noisy at 3 s, the pair trips soon after
        executive.run_for(0.01)
        views = [ReplicaView.of(replica.outputs) for replica in pair.replicas]
        keys = [replica.vote_key() for replica in pair.replicas]
        for view, key in zip(views, keys, strict=True):
            assert key == tuple(getattr(view, name) for name in ReplicaView.__slots__)
        keys_differed |= keys[0] != keys[1]
    assert keys_differed
    assert pair.tripped_by is PairEventKind.DISAGREEMENT
