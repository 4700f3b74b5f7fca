"""The simulated operator: its step API on status reports, and the service's threaded mode
against a real onboard node."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from fastapi.testclient import TestClient

from protocol import messages as m
from tests.conftest import wait_for
from tests.trackside.conftest import headers_of, running_service, running_vehicle
from trackside.simulated_operator import SIMULATED_OPERATOR, SimulatedOperator

REARM = m.OperatorRequestKind.EB_REARM
Pending = list[tuple[m.Command, Callable[[m.CommandAck | None], None]]]


def _status(vehicle: str, now_s: float, *requests: m.OperatorRequest) -> m.StatusReport:
    vital = m.VitalControlStatus(
        eb_commanded=True,
        system_decay=False,
        etcs_isolated=False,
        supervision_state="monitoring",
        brake_state="braking",
        etcs_state="inserted",
        standstill=True,
        odometry_efficient=True,
        operator_requests=requests,
    )
    return m.StatusReport(
        vehicle_id=vehicle,
        seq=0,
        sim_time_s=now_s,
        line_id="bologna-ring",
        position_m=0.0,
        speed_mps=0.0,
        acceleration_mps2=0.0,
        traction_force_n=0.0,
        ato_state=m.AtoState.NOT_AVAILABLE,
        etcs_mode=m.EtcsMode.SR,
        sc_state=m.ScState.OFF,
        vital_control=vital,
    )


def _operator(**options: Any) -> tuple[SimulatedOperator, Pending]:
    """An operator whose commands wait in ``pending`` for the test to answer them."""
    pending: Pending = []
    operator = SimulatedOperator(
        lambda command, done: pending.append((command, done)), ["URV1"], reaction_s=1.0, **options
    )
    return operator, pending


def _ack(command: m.Command, accepted: bool) -> m.CommandAck:
    return m.CommandAck(
        vehicle_id=command.vehicle_id,
        command_id=command.command_id,
        accepted=accepted,
        reason=None if accepted else "not at standstill",
        sim_time_s=0.0,
    )


def test_step_answers_after_the_reaction_delay_once_and_only_configured_vehicles() -> None:
    operator, pending = _operator()
    rearm = m.OperatorRequest(kind=REARM, number=3, raised_s=10.0)
    assert operator.step(_status("URV2", 10.0, rearm)) == []  # not configured
    assert operator.step(_status("URV1", 10.0, rearm)) == []  # seen now
    assert operator.step(_status("URV1", 10.9, rearm)) == []  # still reacting
    [sent] = operator.step(_status("URV1", 11.0, rearm))
    assert sent.issued_by == SIMULATED_OPERATOR
    assert sent.body == m.OperatorConfirmCommand(request=REARM, number=3)
    assert operator.outstanding("URV1") == 1
    assert operator.step(_status("URV1", 11.2, rearm)) == []  # no second answer meanwhile
    command, done = pending.pop()
    done(_ack(command, True))
    assert operator.outstanding() == 0
    assert [answer.ack.accepted for answer in operator.take_answers() if answer.ack] == [True]
    assert operator.step(_status("URV1", 12.0, rearm)) == []  # answered: never again
    operator.step(_status("URV1", 12.2))  # the vehicle took the confirmation
    assert operator._seen_s == {}
    assert operator._sent == set()


def test_step_tries_again_after_a_refusal_or_a_timeout_and_skips_other_kinds() -> None:
    operator, pending = _operator()
    rearm = m.OperatorRequest(kind=REARM, number=4, raised_s=0.0)
    isolation = m.OperatorRequest(kind=m.OperatorRequestKind.ETCS_ISOLATION, number=5, raised_s=0.0)
    operator.step(_status("URV1", 0.0, rearm, isolation))
    [first] = operator.step(_status("URV1", 1.0, rearm, isolation))
    assert first.body.request is REARM  # type: ignore[union-attr]
    pending.pop()[1](_ack(first, False))
    assert operator.step(_status("URV1", 1.5, rearm)) == []  # a new reaction delay
    [second] = operator.step(_status("URV1", 2.5, rearm))
    pending.pop()[1](None)  # the query ended with no answer
    assert operator.outstanding() == 0
    assert operator.step(_status("URV1", 3.0, rearm)) == []
    assert len(operator.step(_status("URV1", 4.0, rearm))) == 1
    assert second.command_id > first.command_id
    confirmed = m.OperatorRequest(kind=REARM, number=4, raised_s=0.0, confirmed=True)
    only_isolation, _ = _operator(kinds=[m.OperatorRequestKind.ETCS_ISOLATION])
    only_isolation.step(_status("URV1", 0.0, confirmed, isolation))
    [sent] = only_isolation.step(_status("URV1", 1.0, confirmed, isolation))
    assert sent.body == m.OperatorConfirmCommand(
        request=m.OperatorRequestKind.ETCS_ISOLATION, number=5
    )


@pytest.mark.e2e
def test_the_service_operator_rearms_a_real_vehicle_and_is_audited(
    router_endpoint: str, tmp_path: Any
) -> None:
    url = f"sqlite:///{tmp_path / 'ts.db'}"
    with (
        running_service(
            router_endpoint, url, simulated_operators=("URV1",), simulated_operator_reaction_s=0.2
        ) as client,
        running_vehicle(router_endpoint),
    ):
        admin = headers_of(client, "admin")
        assert wait_for(lambda: _vehicle(client, admin).get("alive") is True)
        assert _vehicle(client, admin)["simulated_operator"] is True

        def rearmed() -> bool:
            status = _vehicle(client, admin).get("status") or {}
            vital = status.get("vital_control") or {}
            return vital.get("eb_commanded") is False

        assert wait_for(rearmed, 15.0)
        audit = client.get("/api/v1/audit", headers=admin).json()
        answers = [entry for entry in audit if entry["user"] == SIMULATED_OPERATOR]
        rearms = [e for e in answers if e["action"] == "operator_confirm.eb_rearm"]
        assert rearms, audit
        assert rearms[-1]["result"] == "accepted"
        assert {entry["vehicle_id"] for entry in answers} == {"URV1"}


def _vehicle(client: TestClient, headers: dict[str, str]) -> dict[str, Any]:
    response = client.get("/api/v1/vehicles/URV1", headers=headers)
    return dict(response.json()) if response.status_code == 200 else {}
