"""The RBC's separation on a shared line (issue 23): MAs cut behind the train ahead, extended as
it moves on, shortened or revoked when a train turns up ahead."""

from __future__ import annotations

import random

import pytest

from protocol import messages as m
from tests.trackside.reports import status_report
from trackside.errors import VehicleNotPlacedError
from trackside.rbc import MovementAuthorityIssue, RbcEmulator
from trackside.separation import MovingBlock
from trackside.separation_supervisor import SeparationSupervisor

Change = m.MovementAuthorityChange
RING_M = 5700.0


class Reports:
    """The RBC's position lookup: each vehicle's latest report."""

    def __init__(self) -> None:
        self.latest: dict[str, m.StatusReport] = {}

    def __call__(self, vehicle_id: str) -> m.StatusReport | None:
        return self.latest.get(vehicle_id)


class Line:
    """An RBC with a supervisor, and the trains' reports fed to both."""

    def __init__(self, line_id: str = "open", ring_m: float | None = None) -> None:
        self.line_id = line_id
        self.reports = Reports()
        self.rbc = RbcEmulator(clock=lambda: 0.0, positions=self.reports)
        self.heard: list[m.MovementAuthorityMessage] = []
        self.rbc.add_listener(self.heard.append)
        rings = {} if ring_m is None else {line_id: ring_m}
        self.supervisor = SeparationSupervisor(
            self.rbc, MovingBlock(margin_m=50.0, ring_length_m=rings.get), extension_step_m=50.0
        )

    def report(self, vehicle_id: str, position_m: float) -> None:
        report = status_report(vehicle_id, position_m, line_id=self.line_id)
        self.reports.latest[vehicle_id] = report
        self.supervisor.on_report(report, 0.0)

    def place(self, vehicle_id: str, position_m: float) -> None:
        self.supervisor.register(vehicle_id, train_length_m=6.0)
        self.report(vehicle_id, position_m)

    def route(self, end_m: float, start_m: float = 0.0) -> MovementAuthorityIssue:
        return MovementAuthorityIssue(
            line_id=self.line_id, line_version="v1", start_m=start_m, end_of_authority_m=end_m
        )

    def eoa(self, vehicle_id: str) -> float | None:
        current = self.rbc.current(vehicle_id)
        return (
            None
            if current is None or current.authority is None
            else (current.authority.end_of_authority_m)
        )


def test_an_ma_ends_the_margin_behind_the_train_ahead_with_its_rear_as_danger_point() -> None:
    line = Line()
    line.place("URV2", 600.0)
    line.place("URV1", 100.0)
    message = line.supervisor.request("URV1", line.route(2000.0))
    assert message.authority is not None
    # URV2's min safe rear end: 600 − 2 − 6 = 592; the EoA 50 m behind it.
    assert message.authority.end_of_authority_m == pytest.approx(542.0)
    assert message.authority.danger_point_m == 50.0
    # The leader alone on the line gets its whole route.
    assert line.supervisor.request("URV2", line.route(3000.0)).authority.end_of_authority_m == (  # type: ignore[union-attr]
        3000.0
    )


def test_a_train_no_report_has_placed_gets_no_ma() -> None:
    line = Line()
    line.supervisor.register("URV1", train_length_m=6.0)
    with pytest.raises(VehicleNotPlacedError, match="URV1"):
        line.supervisor.request("URV1", line.route(900.0))
    assert line.heard == []


def test_the_ma_is_extended_as_the_train_ahead_moves_on_by_steps_then_to_the_route() -> None:
    line = Line()
    line.place("URV2", 600.0)
    line.place("URV1", 100.0)
    line.supervisor.request("URV1", line.route(1000.0))
    line.report("URV2", 620.0)  # 20 m gained: under the 50 m step, no message
    assert line.eoa("URV1") == pytest.approx(542.0)
    line.report("URV2", 700.0)
    assert line.eoa("URV1") == pytest.approx(642.0)
    line.report("URV2", 1500.0)  # the route's end is in reach: extended to it, not beyond
    assert line.eoa("URV1") == 1000.0
    changes = [msg.change for msg in line.heard if msg.vehicle_id == "URV1"]
    assert changes == [Change.ISSUED, Change.EXTENDED, Change.EXTENDED]
    danger = line.rbc.current("URV1").authority.danger_point_m  # type: ignore[union-attr]
    assert danger == 0.0  # the route's own end again


def test_a_train_placed_ahead_shortens_the_ma_and_one_alongside_revokes_it() -> None:
    line = Line()
    line.place("URV1", 100.0)
    line.supervisor.request("URV1", line.route(1000.0))
    assert line.eoa("URV1") == 1000.0
    line.place("URV3", 400.0)  # rear 392: URV1 may reach 342
    assert line.eoa("URV1") == pytest.approx(342.0)
    assert line.heard[-1].change is Change.SHORTENED
    line.place("URV4", 140.0)  # rear 132, 30 m ahead of URV1's front: no room at all
    assert line.heard[-1].change is Change.REVOKED
    assert line.eoa("URV1") is None
    # Revoked, the train's route is dropped: nothing extends it again behind URV4's back.
    line.report("URV4", 3000.0)
    assert line.eoa("URV1") is None


def test_on_a_ring_the_ma_is_cut_in_its_own_unwrapped_frame() -> None:
    """URV1 near the end of the lap asks for an EoA beyond it (unwrapped, 6100 m = 400 m into
    the next lap); URV2 stands at 150 m of the next lap."""
    line = Line("ring", ring_m=RING_M)
    line.place("URV2", 150.0)
    line.place("URV1", 5500.0)
    message = line.supervisor.request("URV1", line.route(6100.0, start_m=5450.0))
    assert message.authority is not None
    # URV2's rear 142 m, i.e. 5842 m unwrapped; less the margin: 5792 m.
    assert message.authority.end_of_authority_m == pytest.approx(5792.0)


def test_on_a_ring_a_train_standing_at_its_eoa_is_extended_as_the_leader_leaves() -> None:
    """The train held behind stops at its EoA with its max safe front end (estimate + 2 m)
    a little beyond it: that EoA is just behind its front, not a lap ahead of it. Found by a
    two-train run on the ring, where the RBC took it for a lap and tried to shorten the MA."""
    line = Line("ring", ring_m=RING_M)
    line.place("URV1", 2000.0)
    line.place("URV2", 300.0)
    line.supervisor.request("URV2", line.route(5950.0, start_m=250.0))
    assert line.eoa("URV2") == pytest.approx(1942.0)  # URV1's rear 1992, less the margin
    line.report("URV2", 1941.0)  # standing at it: its max safe front end at 1943
    assert line.eoa("URV2") == pytest.approx(1942.0)
    assert [msg.change for msg in line.heard] == [Change.ISSUED]
    line.report("URV1", 2100.0)
    assert line.eoa("URV2") == pytest.approx(2042.0)
    assert line.heard[-1].change is Change.EXTENDED


@pytest.mark.parametrize("seed", range(20))
def test_on_a_ring_a_recomputed_limit_does_not_shorten_the_ma_it_granted(seed: int) -> None:
    """Round a ring, the limit recomputed from the same reports differs from the granted EoA by
    rounding alone: no shortening (nor, for a train standing at it, a revocation)."""
    rng = random.Random(seed)
    line = Line("ring", ring_m=RING_M)
    lead = rng.uniform(0.0, RING_M)
    follower = (lead - rng.uniform(100.0, 1500.0)) % RING_M
    line.place("URV1", lead)
    line.place("URV2", follower)
    line.supervisor.request("URV2", line.route(follower - 50.0 + RING_M, start_m=follower - 20.0))
    eoa = line.eoa("URV2")
    assert eoa is not None
    for _ in range(5):
        line.report("URV2", (eoa - rng.uniform(3.0, 8.0)) % RING_M)
        line.report("URV1", lead)
    assert [msg.change for msg in line.heard] == [Change.ISSUED]


def test_a_withdrawn_train_bounds_no_one() -> None:
    line = Line()
    line.place("URV2", 600.0)
    line.place("URV1", 100.0)
    line.supervisor.request("URV1", line.route(1000.0))
    line.supervisor.withdraw("URV2")
    line.report("URV1", 110.0)
    assert line.eoa("URV1") == 1000.0


def test_bad_parameters_are_refused() -> None:
    line = Line()
    with pytest.raises(ValueError, match="extension step"):
        SeparationSupervisor(line.rbc, MovingBlock(margin_m=1.0), extension_step_m=-1.0)
    with pytest.raises(ValueError, match="train length"):
        line.supervisor.register("URV1", train_length_m=float("nan"))
