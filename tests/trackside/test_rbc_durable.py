"""The RBC across restarts, and its messages fresh (issue 20).

Level 2 on milano-bologna, a real router, a real trackside service (twice, on one database) and
a real onboard node in lockstep: an MA and a TSR issued before the trackside restarts are still
the RBC's after it (read, extended, revoked, numbered on), the onboard shakes hands with the new
service and keeps them, an onboard that starts up is given them, and an MA replayed on the wire
(of this session or of the last one) is refused.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
import zenoh
from fastapi.testclient import TestClient

from onboard.freshness import Refusal
from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from protocol import TypedPublisher, TypedSubscriber, ZenohSettings, open_session
from protocol import messages as m
from protocol.registry import MOVEMENT_AUTHORITY
from tests.conftest import wait_for
from tests.e2e.conftest import running_trackside
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.e2e

LINE = "milano-bologna"
MA = "/api/v1/rbc/URV1/ma"
TSR = "/api/v1/rbc/URV1/tsr"
TSR_BODY = {"id": "works-1", "line_id": LINE, "start_m": 2000.0, "end_m": 3000.0, "speed_kmh": 60.0}


def _node(session: zenoh.Session) -> OnboardNode:
    return OnboardNode(
        OnboardSettings(vehicle_id="URV1", line_id=LINE, start_position_m=1000.0),
        session=session,
        clock=SimClock(),
        track_map=TrackMap(load_seed_line(LINE)),
    )


def _running(node: OnboardNode, condition: Callable[[], bool]) -> bool:
    """Run the node a slice at a time (the simulation waits for the wire) until it holds."""

    def step() -> bool:
        node.run(0.2)
        return condition()

    return wait_for(step)


def _eoa_ahead(node: OnboardNode) -> float:
    return node.stack.etcs.output.end_of_authority_distance_m or 0.0


def _tsr_in_force(node: OnboardNode) -> bool:
    return any(t.id == "works-1" for t in node.track_map.temporary_speed_restrictions)


def _ma_id(client: TestClient, headers: dict[str, str]) -> int:
    return int(client.get(MA, headers=headers).json()["movement_authority"]["ma_id"])


def test_the_rbc_keeps_its_mas_and_tsrs_across_a_restart_and_refuses_replays(
    router_endpoint: str, tmp_path: Path
) -> None:
    connect = ZenohSettings(connect=(router_endpoint,))
    sent: list[m.MovementAuthorityMessage] = []
    with open_session(connect) as vehicle_session, open_session(connect) as wire:
        node = _node(vehicle_session)
        tap = TypedSubscriber(
            wire, MOVEMENT_AUTHORITY, on_message=lambda _k, ma: sent.append(ma), vehicle="URV1"
        )
        forger = TypedPublisher(wire, MOVEMENT_AUTHORITY, vehicle="URV1")
        try:
            with running_trackside(router_endpoint, tmp_path) as (client, headers):
                assert _running(node, lambda: node.session_client.established)
                first_session = node.session_client.guard.session_id
                body = {"start_m": 1000.0, "end_of_authority_m": 6000.0, "line_id": LINE}
                assert client.post(MA, json=body, headers=headers).status_code == 201
                assert client.post(TSR, json=TSR_BODY, headers=headers).status_code == 201
                assert _running(node, lambda: _eoa_ahead(node) == pytest.approx(5000.0, abs=1.0))
                assert _running(node, lambda: _tsr_in_force(node))
                issued_id = _ma_id(client, headers)
                # A copy of the MA, replayed on the wire in its own session: refused, counted.
                assert wait_for(lambda: len(sent) == 1)
                assert sent[0].freshness is not None
                assert sent[0].freshness.session_id == first_session
                forger.put(sent[0])
                refused = node.session_client.guard.refused
                assert _running(node, lambda: refused[Refusal.REPLAYED] == 1)

            # The trackside restarts on the same database.
            with running_trackside(router_endpoint, tmp_path) as (client, headers):
                assert _ma_id(client, headers) == issued_id
                restrictions = client.get(TSR, headers=headers).json()
                assert [r["restriction_id"] for r in restrictions] == ["works-1"]
                # The onboard loses its session (no acknowledgement), shakes hands with the new
                # service at once and is given the same MA and TSR: nothing changes on board.
                assert _running(
                    node,
                    lambda: (
                        node.session_client.established
                        and node.session_client.guard.session_id != first_session
                    ),
                )
                assert _eoa_ahead(node) == pytest.approx(5000.0, abs=1.0)
                assert _tsr_in_force(node)
                assert node.intake.last_ma_id == issued_id
                # The restarted RBC goes on from where it was: extended, numbered on.
                extended = client.post(
                    f"{MA}/extend", json={"end_of_authority_m": 9000.0}, headers=headers
                )
                assert extended.status_code == 200, extended.text
                assert _ma_id(client, headers) == issued_id + 1
                assert _running(node, lambda: _eoa_ahead(node) == pytest.approx(8000.0, abs=1.0))
                # The first session's MA, replayed now: of another session, refused.
                forger.put(sent[0])
                assert _running(node, lambda: refused[Refusal.OTHER_SESSION] == 1)
                assert node.intake.last_ma_id == issued_id + 1

                # The vehicle restarts: its new onboard is given the MA and the TSR in force.
                node.close()
                node = _node(vehicle_session)
                assert _running(node, lambda: node.intake.last_ma_id == issued_id + 1)
                assert _eoa_ahead(node) == pytest.approx(8000.0, abs=1.0)
                assert _tsr_in_force(node)

                # A revocation after the restart reaches the vehicle: an emergency stop.
                assert client.delete(MA, headers=headers).status_code == 200
                assert _running(node, lambda: node.intake.last_ma_id == issued_id + 2)
                assert node.stack.etcs.mode is m.EtcsMode.TR  # tripped: the MA is withdrawn
                assert client.get(MA, headers=headers).status_code == 404
        finally:
            tap.close()
            forger.close()
            node.close()
