"""The service planning journeys against each other (issue 23): over REST and Zenoh, a journey
timed into a booked one is delayed, stored as its next version and sent; a version the vehicle
rejects is withdrawn from the store; the answer and the audit say what the planner did."""

from __future__ import annotations

from typing import Any

import zenoh

from protocol import TypedPublisher, TypedSubscriber, declare_liveliness
from protocol import messages as m
from protocol.registry import JOURNEY_PROFILE, JOURNEY_PROFILE_ACK, STATUS
from tests.conftest import wait_for
from tests.trackdb.ring_journeys import ring_journey
from tests.trackside.conftest import ADMIN, MakeClient, login
from tests.trackside.reports import status_report
from tests.trackside.test_separation_service import handshake

# two-trains-planned's journeys: the one behind is timed into the lead's.
LEAD = ring_journey(
    "lead", 900.0, [("east", 150.0, 180.0), ("south", 330.0, 350.0), ("north", 640.0, None)]
)
BEHIND = ring_journey("behind", 300.0, [("east", 185.0, 215.0), ("south", 400.0, None)])


class Onboards:
    """Two vehicles' side of the links: liveliness, sessions, status, and JPAcks that accept
    or reject as told."""

    def __init__(self, session: zenoh.Session) -> None:
        self.session = session
        self.accept = {"URV1": True, "URV2": True}
        self.journeys: dict[str, str | None] = {"URV1": None, "URV2": None}
        self.received: list[m.JourneyProfile] = []
        self.tokens = [declare_liveliness(session, f"ato/alive/ob/{v}") for v in self.accept]
        self.status = {v: TypedPublisher(session, STATUS, vehicle=v) for v in self.accept}
        self.acks = {
            v: TypedPublisher(session, JOURNEY_PROFILE_ACK, vehicle=v) for v in self.accept
        }
        self.seq = 0
        self.profiles = TypedSubscriber(
            session, JOURNEY_PROFILE, on_message=self._on_profile, vehicle="*"
        )

    def _on_profile(self, _key: str, profile: m.JourneyProfile) -> None:
        self.received.append(profile)
        accepted = self.accept[profile.vehicle_id]
        if accepted:
            self.journeys[profile.vehicle_id] = profile.journey_id
        ack = m.JourneyProfileAck(
            vehicle_id=profile.vehicle_id,
            journey_id=profile.journey_id,
            version=profile.version,
            accepted=accepted,
            reason=None if accepted else "not now",
        )
        self.acks[profile.vehicle_id].put(ack)

    def report(self) -> None:
        """Both vehicles' status at the same simulated time, 0.2 s on."""
        self.seq += 1
        for vehicle_id, position in (("URV1", 900.0), ("URV2", 300.0)):
            report = status_report(vehicle_id, position, line_id="bologna-ring").model_copy(
                update={
                    "seq": self.seq,
                    "sim_time_s": 0.2 * self.seq,
                    "journey_id": self.journeys[vehicle_id],
                }
            )
            self.status[vehicle_id].put(report)


def _send(client: Any, headers: dict[str, str], vehicle_id: str, journey_id: str) -> Any:
    return client.post(
        f"/api/v1/vehicles/{vehicle_id}/journey-profile",
        json={"journey_id": journey_id, "timeout_s": 5.0},
        headers=headers,
    )


def test_a_journey_timed_into_a_booked_one_is_delayed_stored_and_withdrawn_if_rejected(
    make_client: MakeClient, zenoh_pair: tuple[zenoh.Session, zenoh.Session]
) -> None:
    client = make_client(separation_margin_m=50.0)
    headers = login(client, *ADMIN)
    _, onboard = zenoh_pair
    onboards = Onboards(onboard)
    bridge = client.app.state.bridge  # type: ignore[attr-defined]
    for vehicle_id in onboards.accept:
        handshake(onboard, vehicle_id)

    def reported() -> bool:
        onboards.report()
        return all(
            (s := bridge.snapshot(v)) is not None and s.status is not None for v in onboards.accept
        )

    assert wait_for(reported)
    for journey in (LEAD, BEHIND):
        stored = client.post(
            "/api/v1/journeys", json=journey.model_dump(mode="json"), headers=headers
        )
        assert stored.status_code == 201, stored.text
    for vehicle_id in onboards.accept:
        held = client.post(f"/api/v1/vehicles/{vehicle_id}/select", headers=headers)
        assert held.status_code == 200, held.text

    # The lead's journey is the first on the line: sent as stored.
    lead = _send(client, headers, "URV1", "lead")
    assert lead.status_code == 200, lead.text
    assert (lead.json()["version"], lead.json()["delay_s"]) == (1, 0.0)

    def lead_running() -> bool:
        onboards.report()
        return bool(bridge.snapshot("URV1").status.journey_id == "lead")

    assert wait_for(lead_running)

    # A new journey the lead's vehicle rejects: it runs the one it had, still planned against.
    onboards.accept["URV1"] = False
    kept = _send(client, headers, "URV1", "lead")
    assert kept.status_code == 200, kept.text
    assert kept.json()["accepted"] is False
    onboards.accept["URV1"] = True

    # The one behind, rejected by its vehicle: delayed, sent as version 2, then withdrawn.
    onboards.accept["URV2"] = False
    rejected = _send(client, headers, "URV2", "behind")
    assert rejected.status_code == 200, rejected.text
    answer = rejected.json()
    assert answer["accepted"] is False
    assert answer["version"] == 2
    assert answer["delay_s"] > 0.0
    assert "URV2 would run" in answer["conflict"]
    assert onboards.received[-1].timing_points[0].arrival_time_s == 185.0 + answer["delay_s"]
    versions = client.get("/api/v1/journeys/behind", headers=headers).json()
    assert versions["version"] == 1

    # Accepted, the delayed version stays stored and the train is booked.
    onboards.accept["URV2"] = True
    accepted = _send(client, headers, "URV2", "behind")
    assert accepted.status_code == 200, accepted.text
    assert accepted.json()["accepted"] is True
    assert accepted.json()["delay_s"] == answer["delay_s"]
    assert client.get("/api/v1/journeys/behind", headers=headers).json()["version"] == 2
    entries = client.get("/api/v1/audit", params={"vehicle_id": "URV2"}, headers=headers).json()
    outcomes = [
        (entry["result"], entry["request"].get("delay_s"), entry["request"].get("withdrawn"))
        for entry in sorted(entries, key=lambda entry: entry["id"])
        if entry["action"] == "journey_profile" and entry["result"] != "requested"
    ]
    assert outcomes[-2:] == [
        ("refused", answer["delay_s"], True),
        ("accepted", answer["delay_s"], None),
    ]
    stats = client.app.state.commands.planner.stats  # type: ignore[attr-defined]
    assert (stats.as_stored, stats.delayed, stats.refused) == (2, 2, 0)
