"""A trackside restart in the middle of an engaged journey: the vehicle carries on, and the
journey, the hold, the audit, the events and the telemetry are all there after the restart."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from protocol import ZenohSettings, open_session
from protocol import messages as m
from tests.conftest import wait_for
from tests.e2e.conftest import running_trackside
from tests.e2e.test_field_sequence import Vehicle, _engage, _send_journey, _to_standstill_after_rd

pytestmark = pytest.mark.e2e

V = "/api/v1/vehicles/URV1"
TELEMETRY = f"{V}/telemetry?limit=100000"


def test_restart_while_engaged(router_endpoint: str, tmp_path: Path) -> None:
    connect = ZenohSettings(connect=(router_endpoint,))
    with open_session(connect) as session, open_session(connect) as operator:
        vehicle = Vehicle(session, operator)
        stack = vehicle.stack
        try:
            with running_trackside(router_endpoint, tmp_path) as (client, headers):
                vehicle.attach(client)
                _to_standstill_after_rd(vehicle)
                _send_journey(vehicle, client, headers)
                _engage(vehicle)
                vehicle.run(30.0)
                assert wait_for(lambda: _has_telemetry(client, headers, 20))
                before: dict[str, Any] = {
                    path: client.get(path, headers=headers).json()
                    for path in ("/api/v1/audit", f"{V}/events", TELEMETRY)
                }
            vehicle.attach(None)
            position_m = vehicle.node.plant.position_m
            vehicle.run(1.0)  # the trackside is down for one second of the vehicle's time
            with running_trackside(router_endpoint, tmp_path) as (client, headers):
                vehicle.attach(client)
                # Lockstep runs far faster than wall time: let the new service join first.
                assert wait_for(lambda: client.get(V, headers=headers).json()["alive"])

                # The report sent while the service was down is never acknowledged: the
                # onboard loses the session after its timeout and asks the new service for one
                # at once (no fallback stop: the journey goes on).
                def established_again() -> bool:
                    codes = [e.code for e in vehicle.events]
                    return "session.lost" in codes and codes.count("session.established") >= 2

                assert vehicle.run_until(established_again, 60.0)
                vehicle.run(5.0)
                assert stack.ato_state is m.AtoState.ENGAGED, "\n".join(
                    f"{e.sim_time_s} {e.code} {e.text}" for e in vehicle.events[-30:]
                )
                assert not stack.driving.fallback_active
                assert vehicle.node.session_client.established
                assert vehicle.node.plant.position_m > position_m + 50.0
                assert vehicle.node.plant.speed_mps > 1.0
                assert wait_for(lambda: client.get(V, headers=headers).json()["status"])
                status = client.get(V, headers=headers).json()
                assert status["status"]["journey_id"] == "field-test"
                assert status["status"]["ato_state"] == "EG"
                assert status["holder"] == "admin"  # the hold survived the restart
                assert client.get("/api/v1/journeys/field-test", headers=headers).status_code == 200
                assert wait_for(lambda: _has_telemetry(client, headers, len(before[TELEMETRY]) + 5))
                after = {path: client.get(path, headers=headers).json() for path in before}
                for path, rows in before.items():
                    assert after[path][: len(rows)] == rows, path  # nothing lost or changed
                codes = [event["code"] for event in after[f"{V}/events"]]
                assert "ato.engaged" in codes
                assert "session.established" in codes
        finally:
            vehicle.close()


def _has_telemetry(client: Any, headers: dict[str, str], count: int) -> bool:
    return len(client.get(TELEMETRY, headers=headers).json()) >= count
