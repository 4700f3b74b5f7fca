"""The seed 000 field sequence end to end: router + trackside service + onboard, all real.

RD at 30 km/h in SR → the balise group at 150 m brings FS → stop → the journey profile is sent
through the REST API and acknowledged → AD engaged → three stops → end of journey. Then: the
trackside goes away while the vehicle is engaged, and the vehicle stops at its next stopping
point on its own. The onboard runs in lockstep (SimClock); the test advances it in slices and
acts between them, as the operator would.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import zenoh
from fastapi.testclient import TestClient

from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import SimClock
from protocol import TypedSubscriber, ZenohSettings, open_session
from protocol import messages as m
from protocol.registry import EVENT
from tests.conftest import wait_for
from tests.e2e.conftest import running_trackside
from tests.operator import LockstepOperator
from trackdb import TrackMap, load_seed_line

pytestmark = pytest.mark.e2e

RING = TrackMap(load_seed_line("bologna-ring"))


class Vehicle:
    """The onboard in lockstep, with an operator's hands: commands and a running clock."""

    def __init__(
        self, session: zenoh.Session, operator: zenoh.Session, *, vital_control: bool = True
    ) -> None:
        self.node = OnboardNode(
            OnboardSettings(vehicle_id="URV1", vital_control=vital_control),
            session=session,
            clock=SimClock(),
            track_map=RING,
        )
        self.operator = operator
        self.events: list[m.Event] = []
        self._events = TypedSubscriber(
            operator, EVENT, on_message=lambda _k, e: self.events.append(e), vehicle="URV1"
        )
        self.hands = LockstepOperator(operator, self.node, trackside=None)
        """Answers the Vital Control's vigilance and EB-rearm requests between slices, through
        the trackside service attached (:meth:`attach`)."""

    def attach(self, client: TestClient | None) -> None:
        """Command through this trackside service (the one the vehicle holds a session with);
        None: the service is gone."""
        bridge = None if client is None else client.app.state.bridge  # type: ignore[attr-defined]
        self.hands.attach(bridge)

    def run(self, duration_s: float) -> None:
        self.hands.run(duration_s)

    def run_until(self, condition: Callable[[], bool], limit_s: float, step_s: float = 1.0) -> bool:
        """Advance simulated time until ``condition`` holds (checked every ``step_s``)."""
        return self.hands.run_until(condition, limit_s, step_s)

    def command(self, body: Any) -> m.CommandAck:
        return self.hands.command(body)

    def while_running(self, action: Callable[[], Any]) -> Any:
        """Do ``action`` (which waits for the vehicle) while the vehicle runs."""
        result: list[Any] = []
        worker = threading.Thread(target=lambda: result.append(action()), daemon=True)
        worker.start()
        while worker.is_alive():
            self.hands.run(0.2)
        return result[0]

    @property
    def stack(self) -> Any:
        return self.node.stack

    def close(self) -> None:
        self._events.close()
        self.node.close()


def _field_journey(client: TestClient, headers: dict[str, str], start_m: float) -> None:
    journey = {
        "id": "field-test",
        "line_id": "bologna-ring",
        "start_position_m": start_m,
        "max_speed_mps": 40 / 3.6,
        "timing_points": [
            {
                "id": "east",
                "stopping_point_id": "east",
                "arrival_time_s": 300.0,
                "departure_time_s": 320.0,
            },
            {
                "id": "south",
                "stopping_point_id": "south",
                "arrival_time_s": 550.0,
                "departure_time_s": 570.0,
            },
            {
                "id": "north",
                "stopping_point_id": "north",
                "arrival_time_s": 1000.0,
                "end_of_journey": True,
            },
        ],
    }
    response = client.post("/api/v1/journeys", json=journey, headers=headers)
    assert response.status_code == 201, response.text


def _to_standstill_after_rd(vehicle: Vehicle) -> None:
    node = vehicle.node
    assert vehicle.run_until(
        lambda: node.session_client.established and node.track_database.versions_match,
        30.0,
        step_s=0.2,
    )
    assert node.stack.etcs.mode is m.EtcsMode.SR
    assert vehicle.command(m.RemoteDrivingTargetCommand(target_speed_mps=30 / 3.6)).accepted
    assert vehicle.run_until(lambda: node.stack.etcs.mode is m.EtcsMode.FS, 60.0)
    assert node.plant.position_m > 150.0  # the balise group brought FS
    assert vehicle.command(m.RemoteDrivingTargetCommand(target_speed_mps=0.0)).accepted
    assert vehicle.run_until(lambda: node.plant.speed_mps == 0.0, 60.0)


def _send_journey(vehicle: Vehicle, client: TestClient, headers: dict[str, str]) -> None:
    _field_journey(client, headers, RING.normalise(vehicle.node.plant.position_m))
    selected = client.post("/api/v1/vehicles/URV1/select", headers=headers)
    assert selected.status_code == 200, selected.text
    response = vehicle.while_running(
        lambda: client.post(
            "/api/v1/vehicles/URV1/journey-profile",
            json={"journey_id": "field-test"},
            headers=headers,
        )
    )
    assert response.status_code == 200, [(e.code, e.text) for e in vehicle.events][-30:]
    assert response.json()["accepted"] is True


def _engage(vehicle: Vehicle) -> None:
    assert vehicle.run_until(lambda: vehicle.stack.ato_state is m.AtoState.READY, 10.0, 0.2)
    assert vehicle.command(m.EngageCommand()).accepted
    assert vehicle.run_until(lambda: vehicle.stack.ato_state is m.AtoState.ENGAGED, 2.0, 0.2)


def test_the_seed_000_field_sequence_on_bologna_ring(
    router_endpoint: str, trackside: tuple[TestClient, dict[str, str]]
) -> None:
    client, headers = trackside
    connect = ZenohSettings(connect=(router_endpoint,))
    with open_session(connect) as session, open_session(connect) as operator:
        vehicle = Vehicle(session, operator)
        vehicle.attach(client)
        try:
            _to_standstill_after_rd(vehicle)
            _send_journey(vehicle, client, headers)
            _engage(vehicle)
            assert vehicle.stack.etcs.mode is m.EtcsMode.AD
            stack = vehicle.stack
            vehicle.run(100.0)
            report = vehicle.node.status(vehicle.node.clock.now_ns)
            assert report.next_timing_point_id == "east"
            assert [a.timing_point_id for a in report.arrivals] == ["east", "south", "north"]
            assert report.arrivals[0].estimated_s == pytest.approx(300.0, abs=2.0)
            assert report.position_confidence_m is not None
            assert report.position_confidence_m > 5.0
            stops: list[tuple[str, float, float]] = []

            def record_stop() -> bool:
                stop = stack.driving.stopped_at(
                    vehicle.node.plant.position_m, vehicle.node.plant.speed_mps
                )
                if stop is not None and (not stops or stops[-1][0] != stop.timing_point_id):
                    error = vehicle.node.plant.position_m - stack.driving.progress.origin_m
                    stops.append(
                        (
                            stop.timing_point_id,
                            stack.driving.journey_time_s(vehicle.node.clock.now_s),
                            error - stop.distance_m,
                        )
                    )
                # The journey ends on the fused speed reading zero; the train comes to rest a
                # few ticks later under the brake.
                plant = vehicle.node.plant
                return stack.ato_state is m.AtoState.NOT_AVAILABLE and plant.speed_mps == 0.0

            assert vehicle.run_until(record_stop, 1100.0, step_s=0.4)
            assert [name for name, _, _ in stops] == ["east", "south", "north"]
            for (_, arrival_s, error_m), planned_s in zip(
                stops, (300.0, 550.0, 1000.0), strict=True
            ):
                assert abs(error_m) <= 0.5
                assert abs(arrival_s - planned_s) <= 2.5
            assert RING.normalise(vehicle.node.plant.position_m) == pytest.approx(550.0, abs=0.5)
            # The ADF drove the journey without a single ETCS intervention.
            etcs_events = [
                (e.sim_time_s, e.code, e.text)
                for e in vehicle.events
                if e.code.startswith(("etcs", "ato", "session"))
            ]
            assert stack.etcs.service_brake_interventions == 0, etcs_events
            assert stack.etcs.emergency_brake_interventions == 0
            assert wait_for(lambda: any(e.code == "journey.accepted" for e in vehicle.events))
            vehicle.run(1.0)  # the next status reports carry the end of journey

            def reported() -> dict[str, Any]:
                vehicle_json = client.get("/api/v1/vehicles/URV1", headers=headers).json()
                return dict(vehicle_json["status"])

            assert wait_for(lambda: reported()["ato_state"] == "NA")
            assert reported()["journey_id"] == "field-test"
        finally:
            vehicle.close()


def test_trackside_loss_while_engaged_ends_at_the_next_stopping_point(
    router_endpoint: str, tmp_path: Path
) -> None:
    connect = ZenohSettings(connect=(router_endpoint,))
    with open_session(connect) as session, open_session(connect) as operator:
        # Without the Vital Control: with the trackside gone nobody may answer its vigilance
        # requests (every 30 s), and it would brake at the first deadline (the zenoh-link-loss
        # scenario shows that); here the ATO-OB's own fallback is under test.
        vehicle = Vehicle(session, operator, vital_control=False)
        try:
            with running_trackside(router_endpoint, tmp_path) as (client, headers):
                vehicle.attach(client)
                _to_standstill_after_rd(vehicle)
                _send_journey(vehicle, client, headers)
                _engage(vehicle)
                vehicle.run(60.0)
            vehicle.attach(None)
            # The trackside is gone (its service and Zenoh session closed) in the middle of the
            # first leg: the onboard notices the silence and stops at the next stopping point.
            stack = vehicle.stack
            assert vehicle.run_until(lambda: stack.driving.fallback_active, 20.0, 0.2)
            assert wait_for(lambda: any(e.code == "session.lost" for e in vehicle.events))
            assert stack.ato_state is m.AtoState.ENGAGED
            assert vehicle.run_until(
                lambda: (
                    stack.driving.stopped_at(
                        vehicle.node.plant.position_m, vehicle.node.plant.speed_mps
                    )
                    is not None
                ),
                400.0,
            )
            assert RING.normalise(vehicle.node.plant.position_m) == pytest.approx(1975.0, abs=0.5)
            assert vehicle.run_until(lambda: stack.ato_state is m.AtoState.AVAILABLE, 5.0, 0.2)
        finally:
            vehicle.close()


def test_rbc_movement_authorities_reach_the_onboard_etcs(
    router_endpoint: str, trackside: tuple[TestClient, dict[str, str]]
) -> None:
    """Level 2 on milano-bologna: the admin issues, extends and shortens the MA through REST;
    the onboard's ETCS sees each change."""
    client, headers = trackside
    line = TrackMap(load_seed_line("milano-bologna"))
    connect = ZenohSettings(connect=(router_endpoint,))
    with open_session(connect) as session:
        node = OnboardNode(
            OnboardSettings(vehicle_id="URV1", line_id="milano-bologna", start_position_m=1000.0),
            session=session,
            clock=SimClock(),
            track_map=line,
        )
        try:
            etcs = node.stack.etcs

            def eoa_ahead() -> float | None:
                node.run(0.2)
                return etcs.output.end_of_authority_distance_m

            def established() -> bool:
                node.run(0.2)
                return node.session_client.established

            assert wait_for(established)
            url = "/api/v1/rbc/URV1/ma"
            body = {"start_m": 1000.0, "end_of_authority_m": 6000.0, "line_id": "milano-bologna"}
            issued = client.post(url, json=body, headers=headers)
            assert issued.status_code == 201, issued.text
            assert wait_for(lambda: (eoa_ahead() or 0.0) == pytest.approx(5000.0, abs=1.0))
            extended = client.post(
                f"{url}/extend", json={"end_of_authority_m": 9000.0}, headers=headers
            )
            assert extended.status_code == 200, extended.text
            assert wait_for(lambda: (eoa_ahead() or 0.0) == pytest.approx(8000.0, abs=1.0))
            shortened = client.post(
                f"{url}/shorten", json={"end_of_authority_m": 4000.0}, headers=headers
            )
            assert shortened.status_code == 200, shortened.text
            assert wait_for(lambda: (eoa_ahead() or 0.0) == pytest.approx(3000.0, abs=1.0))
        finally:
            node.close()
