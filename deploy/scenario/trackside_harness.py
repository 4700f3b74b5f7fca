"""The trackside of a whole-stack run, and the REST calls the operator and the RBC make.

The trackside service runs in this process (its FastAPI app behind a ``TestClient``, on a
SQLite file in the run's scratch directory, on the run's Zenoh session). The harness acts as an
admin without a password, through a token it issues in the database it owns; it holds the
vehicle as a driver at the console does, and makes the REST calls of the scenario: movement
authorities and TSRs through the RBC's routes, journeys, commands. The run's line is imported
into that database through the lines route at each start (a built-in line is there already; a
line of a file or a user's database is stored as the trackside of a real deployment would have
it), so the trackside plans on the line the vehicle drives on. After each call that sends the
vehicle a message it waits, in wall time, until the vehicle has it, so that the message is
taken at a tick fixed by simulated time.
"""

from __future__ import annotations

import copy
import threading
import time
from pathlib import Path
from typing import Any

import zenoh
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session, sessionmaker

from deploy.scenario.run_context import RunContext, ScenarioRunError, forward_m, wait_for
from deploy.scenario.schema import TemporarySpeedRestriction
from protocol.units import MPS_PER_KMH
from trackside.config import Settings
from trackside.main import create_app
from trackside.models import Role
from trackside.services import audit, users

__all__ = ["JOURNEY_TIMEOUT_S", "TracksideHarness"]

OPERATOR_USER = "scenario"
"""The run's operator: an admin of the run's trackside, without a password."""
JOURNEY_TIMEOUT_S = 30.0
"""How long, in wall time, the operator waits for the vehicle's journey acknowledgement [s]: the
REST route's longest. The vehicle answers at its next commands tick, within the one slice run
while the journey is sent, so the wait is the wire's and the machine's alone (10 s was too short
for a generated run on a machine loaded five times over its cores)."""
EVENT_TIMEOUT_S = 10.0
"""How long, in wall time, the operator looks for an event in the vehicle's log [s]."""
EVENT_POLL_S = 0.05
"""... asking the trackside's REST API this often [s]."""
SLICE_S = 0.2
"""The slice run while a journey is sent (one control period) [s]."""


class TracksideHarness:
    """The trackside service of one run, on a database in ``scratch``."""

    def __init__(self, ctx: RunContext, scratch: Path, zenoh_session: zenoh.Session) -> None:
        self.ctx = ctx
        self.zenoh_session = zenoh_session
        spec = ctx.spec
        simulated = (spec.vehicle.id,) if spec.operator.simulated else ()
        self.settings = Settings(
            database_url=f"sqlite:///{scratch / 'trackside.db'}",
            zenoh_connect=(),
            # No bootstrap admin: the run's operator is a user without a password, holding a
            # token issued in the database the run owns (start): no password hashed at start-up
            # nor checked at a login (two scrypt hashes, 0.9 s of a bologna-ring run).
            admin_user=None,
            admin_password=None,
            simulated_operators=simulated,
            simulated_operator_reaction_s=spec.operator.reaction_s,
            simulated_operator_thread=False,
            # The run's driver selects once and commands whenever the scenario says, however
            # long the wall time in between: its hold must not lapse (a console renews its
            # lease while open; this driver has no console).
            hold_lease_s=24 * 3600.0,
            # Each report taken on arrival, not in 5 ms batches: a run has one train or a few,
            # and in lockstep the onboard waits for each report's acknowledgement at its next
            # status tick (7 ms of wall time at 30x): a batch's wait made it wait there.
            status_intake_period_s=0.0,
        )
        # The run's line goes in through the lines route, whatever its size.
        self._line_document = ctx.node.track_map.line.model_dump_json(round_trip=True)
        line_bytes = len(self._line_document.encode()) + 4096
        if line_bytes > self.settings.max_body_bytes:
            self.settings = self.settings.model_copy(update={"max_body_bytes": line_bytes})
        self.client: TestClient | None = None
        self.headers: dict[str, str] = {}
        self._selected = False

    # -- life cycle ------------------------------------------------------------------------------

    def start(self) -> None:
        """The service (a new app on the same database and Zenoh session), and a login."""
        client = TestClient(create_app(self.settings, zenoh_session=self.zenoh_session))
        client.__enter__()
        self.client = client
        factory: sessionmaker[Session] = client.app.state.session_factory  # type: ignore[attr-defined]
        with factory() as db, db.begin():
            user = users.ensure_token_user(db, OPERATOR_USER, Role.ADMIN)
            token = users.issue_token(db, user, self.settings.token_ttl_s)
        audit.record(
            factory,
            audit.audit_entry(
                user=OPERATOR_USER,
                vehicle_id=None,
                action="token",
                request={"issued_by": "scenario run"},
                result=audit.AuditResult.ACCEPTED,
            ),
        )
        self.headers = {"Authorization": f"Bearer {token}"}
        self._selected = False
        self._store_line()

    def _store_line(self) -> None:
        """Import the run's line (admin, audited); the same version again changes nothing."""
        line = self.ctx.node.track_map.line
        answer = self.rest.post(
            "/api/v1/lines",
            content=self._line_document,
            headers={**self.headers, "Content-Type": "application/json"},
        )
        if answer.status_code not in (200, 201):
            raise ScenarioRunError(
                f"the trackside refused line {line.id!r} ({answer.status_code}): "
                f"{answer.text[:300]}"
            )

    def for_train(self, ctx: RunContext) -> TracksideHarness:
        """The same service, logged in as the same user, for another train of the run (a
        multi-train run: one trackside for all its trains). The service's life cycle stays
        with this harness."""
        view = copy.copy(self)
        view.ctx = ctx
        view._selected = False
        return view

    def stop(self) -> None:
        if self.client is not None:
            self.client.__exit__(None, None, None)
            self.client = None

    @property
    def rest(self) -> TestClient:
        if self.client is None:
            raise ScenarioRunError("the trackside is down")
        return self.client

    @property
    def simulated_operator(self) -> Any:
        """The trackside's simulated operator (None: none, or the trackside is down)."""
        if self.client is None:
            return None
        return self.client.app.state.simulated_operator  # type: ignore[attr-defined]

    def select(self) -> None:
        """Hold the vehicle, as a driver at the console does before commanding it (once the
        trackside has seen it; the hold is stored, selecting again is harmless)."""
        if self._selected:
            return
        url = f"/api/v1/vehicles/{self.ctx.spec.vehicle.id}"
        if not wait_for(lambda: self.rest.get(url, headers=self.headers).status_code == 200):
            raise ScenarioRunError("the trackside never saw the vehicle")
        selected = self.rest.post(f"{url}/select", headers=self.headers)
        if selected.status_code != 200:
            raise ScenarioRunError(f"cannot select the vehicle: {selected.text[:200]}")
        self._selected = True

    # -- the RBC ---------------------------------------------------------------------------------

    def speed_restriction(self, restriction_id: str, fault: TemporarySpeedRestriction) -> None:
        """The RBC (REST, as admin) sends a TSR; the run goes on once the vehicle has it."""
        ctx = self.ctx
        before = ctx.node.inputs_received[2]
        body = {
            "id": restriction_id,
            "line_id": ctx.node.track_map.line.id,
            "start_m": fault.start_m,
            "end_m": fault.end_m,
            "speed_kmh": fault.speed_kmh,
        }
        answer = self.rest.post(
            f"/api/v1/rbc/{ctx.spec.vehicle.id}/tsr", json=body, headers=self.headers
        )
        accepted = answer.status_code == 201
        ctx.log("rbc.tsr", accepted, answer.text[:200])
        if not accepted:
            ctx.failures.append(f"TSR {restriction_id} refused: {answer.text[:200]}")
        elif not wait_for(lambda: ctx.node.inputs_received[2] > before):
            raise ScenarioRunError("the RBC's TSR never reached the vehicle")

    def movement_authority(
        self, end_m: float, *, absolute: bool = False, danger_point_m: float = 0.0
    ) -> Any:
        """The RBC (REST, as admin) issues an MA from here to ``end_m`` (a chainage, or with
        ``absolute`` a position already unwrapped from here), or shortens the one it holds, its
        new end with ``danger_point_m``; the run goes on once the vehicle has the message."""
        node = self.ctx.node
        here = node.track_map.normalise(node.plant.position_m)
        if not absolute:
            end_m = here + forward_m(node, here, end_m)
        url = f"/api/v1/rbc/{self.ctx.spec.vehicle.id}/ma"
        before = node.inputs_received[1]
        if self.rest.get(url, headers=self.headers).status_code == 404 or not absolute:
            body = {
                "start_m": here,
                "end_of_authority_m": end_m,
                "line_id": self.ctx.node.track_map.line.id,
                "danger_point_m": danger_point_m,
            }
            answer = self.rest.post(url, json=body, headers=self.headers)
        else:
            end = {"end_of_authority_m": end_m, "danger_point_m": danger_point_m}
            answer = self.rest.post(f"{url}/shorten", json=end, headers=self.headers)
        if answer.status_code in (200, 201) and not wait_for(
            lambda: node.inputs_received[1] > before
        ):
            raise ScenarioRunError("the RBC's MA never reached the vehicle")
        return answer

    def rbc_state(self) -> tuple[int | None, tuple[str, ...]]:
        """What the RBC holds for the vehicle: its MA's id (None: none) and its TSRs' ids."""
        url = f"/api/v1/rbc/{self.ctx.spec.vehicle.id}"
        answer = self.rest.get(f"{url}/ma", headers=self.headers)
        ma_id = answer.json()["movement_authority"]["ma_id"] if answer.status_code == 200 else None
        tsrs = self.rest.get(f"{url}/tsr", headers=self.headers).json()
        return ma_id, tuple(tsr["restriction_id"] for tsr in tsrs)

    # -- the driver ------------------------------------------------------------------------------

    def command(self, route: str, body: dict[str, Any]) -> Any:
        """A remote-driver command through ``/vehicles/{id}/{route}``; the HTTP answer."""
        return self.rest.post(
            f"/api/v1/vehicles/{self.ctx.spec.vehicle.id}/{route}", json=body, headers=self.headers
        )

    def wait_for_event(self, code: str, timeout_s: float = EVENT_TIMEOUT_S) -> str | None:
        """The text of the vehicle's newest event of ``code`` in the trackside's log, waited
        for in wall time (events travel reliably but not at once); None if none came."""
        deadline = time.monotonic() + timeout_s
        while True:
            answer = self.rest.get(
                f"/api/v1/vehicles/{self.ctx.spec.vehicle.id}/events",
                params={"limit": 1000},
                headers=self.headers,
            )
            if answer.status_code == 200:
                found = [event["text"] for event in answer.json() if event["code"] == code]
                if found:
                    return str(found[-1])
            if time.monotonic() > deadline:
                return None
            time.sleep(EVENT_POLL_S)

    def send_journey(self) -> tuple[bool, str | None]:
        """Store the journey from where the vehicle stands, and send it through the REST API
        while the vehicle runs (it answers at its next commands tick)."""
        ctx = self.ctx
        journey = ctx.spec.journey
        assert journey is not None
        body = {
            "id": journey.id,
            "line_id": ctx.node.track_map.line.id,
            "start_position_m": ctx.node.track_map.normalise(ctx.node.plant.position_m),
            "max_speed_mps": (
                None if journey.max_speed_kmh is None else journey.max_speed_kmh * MPS_PER_KMH
            ),
            "timing_points": [p.model_dump(mode="json") for p in journey.timing_points],
        }
        stored = self.rest.post("/api/v1/journeys", json=body, headers=self.headers)
        if stored.status_code != 201:
            return False, f"journey not stored ({stored.status_code}): {stored.text}"
        answer: list[Any] = []

        def send() -> None:
            answer.append(
                self.command(
                    "journey-profile", {"journey_id": journey.id, "timeout_s": JOURNEY_TIMEOUT_S}
                )
            )

        journeys_before = ctx.node.inputs_received[0]
        sender = threading.Thread(target=send, daemon=True)
        sender.start()
        # The profile reaches the node between slices; the next slice takes it and answers, so
        # the run does not depend on how fast the messages travel: waited for as long as the
        # trackside waits for the answer (gen-1-42, its REST call starved for over 10 s by a
        # campaign run at nice 19 beside the test suite, was refused with a 504).
        received = wait_for(
            lambda: ctx.node.inputs_received[0] > journeys_before,
            sender,
            timeout_s=JOURNEY_TIMEOUT_S,
        )
        if received:
            ctx.run_for(SLICE_S)
        sender.join(JOURNEY_TIMEOUT_S)
        if not answer:
            return False, "the trackside did not answer"
        response = answer[0]
        if response.status_code != 200:
            return False, f"{response.status_code}: {response.text}"
        reply = response.json()
        detail = reply.get("reason")
        if reply.get("delay_s"):  # the trackside's planner timed it later (issue 23)
            detail = f"planned {reply['delay_s']:g} s later: {reply.get('conflict')}"
        return bool(reply["accepted"]), detail
