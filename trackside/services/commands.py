"""Commands to a vehicle on behalf of a user: checked, sent over Zenoh, answered, audited.

Each attempt leaves two audit entries that share a ``request_id`` in their request (for a
command, also its ``command_id``, the id the vehicle acknowledges): the intent (``requested``),
written before anything is sent, so no vehicle is asked anything that is not in the log first
(if the intent cannot be written, the command is not sent); then the outcome, whatever became
of it: accepted or refused by the vehicle, refused by the trackside (vehicle not alive, not held
by the user), timed out, or failed on the link. A command's intent is written in the
transaction that checks the hold and renews its lease; a journey's, in one of its own before
anything is checked.
"""

from __future__ import annotations

import itertools
import time
from contextlib import nullcontext
from dataclasses import dataclass
from functools import partial
from typing import Any

from sqlalchemy.orm import Session, sessionmaker

from protocol import ProtocolError, RequestTimeoutError
from protocol import messages as m
from trackdb.headway import Conflict
from trackdb.journey import JourneyCheck, journey_profile_message
from trackside.bridge import ZenohBridge
from trackside.errors import (
    ConflictError,
    NotFoundError,
    TracksideError,
    VehicleLinkError,
    VehicleTimeoutError,
)
from trackside.journey_planner import Booking, JourneyPlanner, PlannedJourney
from trackside.models import User
from trackside.services import audit, holds
from trackside.services.audit_chain import append, chained
from trackside.services.journeys import (
    StoredJourney,
    create_journey,
    delete_journey_version,
    get_journey,
    line_top_speed_mps,
    validate_journey,
)

__all__ = ["CommandService", "JourneySent"]

JOURNEY_ACTION = "journey_profile"


@dataclass(frozen=True, slots=True)
class JourneySent:
    """A journey profile's outcome: the vehicle's JPAck and what the planner did."""

    ack: m.JourneyProfileAck
    delay_s: float = 0.0
    """How much later the planner timed the journey than it was stored [s]."""
    conflict: Conflict | None = None
    """The conflict the journey as stored had with another train's plan."""


class CommandService:
    """Sends commands and journey profiles for users who hold the vehicle."""

    def __init__(
        self,
        factory: sessionmaker[Session],
        bridge: ZenohBridge,
        *,
        timeout_s: float,
        hold_lease_s: float = holds.DEFAULT_LEASE_S,
    ) -> None:
        self._factory = factory
        self._bridge = bridge
        self.timeout_s = timeout_s
        self.hold_lease_s = hold_lease_s
        self.planner: JourneyPlanner | None = None
        """Plans a journey against the other trains' on its line before it is sent."""
        # Unique across restarts of the service, so a vehicle never sees an id twice.
        self._ids = itertools.count(time.time_ns() // 1000)

    def _audit(
        self,
        user: User,
        vehicle_id: str,
        action: str,
        request: dict[str, Any],
        result: audit.AuditResult,
        detail: str | None = None,
    ) -> None:
        entry = audit.audit_entry(
            user=user.username,
            vehicle_id=vehicle_id,
            action=action,
            request=request,
            result=result,
            detail=detail,
        )
        audit.record(self._factory, entry)

    def _alive(self, vehicle_id: str) -> None:
        snapshot = self._bridge.snapshot(vehicle_id)
        if snapshot is None or not snapshot.alive:
            raise NotFoundError(f"{vehicle_id} is not alive")

    def _check(self, user: User, vehicle_id: str) -> None:
        self._alive(vehicle_id)
        with self._factory() as db, db.begin():  # the holder's command renews the lease
            holds.check_holder(db, vehicle_id, user, lease_s=self.hold_lease_s)

    def _request(
        self,
        user: User,
        vehicle_id: str,
        action: str,
        request: dict[str, Any],
        *,
        needs_hold: bool,
    ) -> None:
        """Audit a command's intent and check it (the vehicle alive, held by ``user``, the
        lease renewed) in one transaction: one write under the audit chain's lock, not two. A
        refused command is audited as its intent followed by the refusal, as if checked after
        the intent was written; a command whose intent cannot be written is not sent."""
        entry = partial(
            audit.audit_entry,
            user=user.username,
            vehicle_id=vehicle_id,
            action=action,
            request=request,
        )
        try:
            self._alive(vehicle_id)
            with chained(self._factory) as db:
                append(db, entry(result=audit.AuditResult.REQUESTED))
                if needs_hold:
                    holds.check_holder(db, vehicle_id, user, lease_s=self.hold_lease_s)
        except (NotFoundError, ConflictError) as exc:
            with chained(self._factory) as db:
                append(db, entry(result=audit.AuditResult.REQUESTED))
                append(db, entry(result=audit.AuditResult.REFUSED, detail=str(exc)))
            raise

    def send(self, user: User, vehicle_id: str, body: m.CommandBody) -> m.CommandAck:
        """Send ``body`` to the vehicle and return its acknowledgement (accepted or refused).

        Raises :class:`NotFoundError` (not alive), :class:`ConflictError` (not held by the
        user), :class:`VehicleTimeoutError`, :class:`VehicleLinkError`.
        """
        action = audit.command_action(body)
        command_id = next(self._ids)
        request = body.model_dump(mode="json") | {
            "request_id": command_id,
            "command_id": command_id,
        }
        # The emergency brake is any driver's to ask for, whoever holds the vehicle.
        braking = isinstance(body, m.EmergencyBrakeCommand)
        self._request(user, vehicle_id, action, request, needs_hold=not braking)
        try:
            command = m.Command(
                vehicle_id=vehicle_id,
                command_id=command_id,
                issued_by=user.username,
                body=body,
            )
            ack = self._bridge.command(command, timeout_s=self.timeout_s)
        except RequestTimeoutError as exc:
            self._audit(user, vehicle_id, action, request, audit.AuditResult.TIMEOUT, str(exc))
            raise VehicleTimeoutError(f"{vehicle_id} did not answer") from exc
        except ProtocolError as exc:
            self._audit(user, vehicle_id, action, request, audit.AuditResult.FAILED, str(exc))
            raise VehicleLinkError(f"{vehicle_id}: {exc}") from exc
        except Exception as exc:  # the intent must not stay without its outcome
            self._audit(user, vehicle_id, action, request, audit.AuditResult.FAILED, repr(exc))
            raise
        result = audit.AuditResult.ACCEPTED if ack.accepted else audit.AuditResult.REFUSED
        self._audit(user, vehicle_id, action, request, result, ack.reason)
        return ack

    def send_journey_profile(
        self, user: User, vehicle_id: str, journey_id: str, version: int | None, timeout_s: float
    ) -> JourneySent:
        """Send a stored journey as the vehicle's journey profile; its JPAck (accepted or
        rejected). With a :attr:`planner`, a journey whose plan conflicts with another train's
        is first delayed and stored as the journey's next version, which is the one sent (and
        withdrawn from the store again when the vehicle rejects it or the link fails); sends
        are then one at a time, from the planning to the booking. Raises as :meth:`send`, and
        :class:`ConflictError` when no session is open, the journey is no longer valid on its
        line or its plan conflicts and cannot be cleared, :class:`NotFoundError` for an unknown
        journey."""
        request: dict[str, Any] = {
            "journey_id": journey_id,
            "version": version,
            "request_id": next(self._ids),
        }
        self._audit(user, vehicle_id, JOURNEY_ACTION, request, audit.AuditResult.REQUESTED)
        planning = nullcontext() if self.planner is None else self.planner.sending
        with planning:
            return self._send_journey(user, vehicle_id, (journey_id, version), timeout_s, request)

    def _send_journey(
        self,
        user: User,
        vehicle_id: str,
        journey: tuple[str, int | None],
        timeout_s: float,
        request: dict[str, Any],
    ) -> JourneySent:
        created = None  # the planner's delayed version, once stored
        previous = None  # the booking of the journey the vehicle ran before
        try:
            self._check(user, vehicle_id)
            if not self._bridge.session_open(vehicle_id):
                raise ConflictError(f"{vehicle_id} has no session open")
            stored, check, line_version, planned = self._planned(user, vehicle_id, *journey)
            request["version"] = stored.version
            if planned is not None and planned.delay_s > 0.0:
                request["delay_s"], created = planned.delay_s, stored
            if self.planner is not None:
                previous = self.planner.forget(vehicle_id)  # booked again once it accepts
            profile = journey_profile_message(
                stored.journey,
                check,
                vehicle_id=vehicle_id,
                version=stored.version,
                track_data_version=line_version,
                status=m.JourneyProfileStatus.VALID,
            )
            ack = self._bridge.send_journey_profile(profile, timeout_s=timeout_s)
        except TracksideError as exc:
            self._kept(vehicle_id, previous)
            self._outcome(user, vehicle_id, request, audit.AuditResult.REFUSED, str(exc), created)
            raise
        except ProtocolError as exc:
            self._kept(vehicle_id, previous)
            self._outcome(user, vehicle_id, request, audit.AuditResult.FAILED, str(exc), created)
            raise VehicleLinkError(f"{vehicle_id}: {exc}") from exc
        except Exception as exc:  # the intent must not stay without its outcome
            self._kept(vehicle_id, previous)
            self._outcome(user, vehicle_id, request, audit.AuditResult.FAILED, repr(exc), created)
            raise
        if ack is None:  # kept: the vehicle may have taken it all the same
            self._outcome(user, vehicle_id, request, audit.AuditResult.TIMEOUT, None, None)
            raise VehicleTimeoutError(f"{vehicle_id} did not acknowledge the journey profile")
        if not ack.accepted:
            self._kept(vehicle_id, previous)
            self._outcome(user, vehicle_id, request, audit.AuditResult.REFUSED, ack.reason, created)
        else:
            self._outcome(user, vehicle_id, request, audit.AuditResult.ACCEPTED, ack.reason, None)
            if self.planner is not None:
                self.planner.book(vehicle_id, stored.journey, check)
        if planned is None:
            return JourneySent(ack)
        return JourneySent(ack, planned.delay_s, planned.conflict)

    def _kept(self, vehicle_id: str, previous: Booking | None) -> None:
        """The vehicle runs the journey it had: planned against again. After a timeout the
        booking stays dropped, as the vehicle may run either journey."""
        if self.planner is not None:
            self.planner.restore(vehicle_id, previous)

    def _outcome(
        self,
        user: User,
        vehicle_id: str,
        request: dict[str, Any],
        result: audit.AuditResult,
        detail: str | None,
        withdraw: StoredJourney | None,
    ) -> None:
        """Audit a journey profile's outcome; withdraw the planner's delayed version that the
        vehicle does not run."""
        if withdraw is not None:
            with self._factory() as db, db.begin():
                delete_journey_version(db, withdraw.journey.id, withdraw.version)
            request["withdrawn"] = True
        self._audit(user, vehicle_id, JOURNEY_ACTION, request, result, detail)

    def _planned(
        self, user: User, vehicle_id: str, journey_id: str, version: int | None
    ) -> tuple[StoredJourney, JourneyCheck, str, PlannedJourney | None]:
        """The stored journey to send, checked on its line, and the planner's answer: a journey
        the planner delayed is stored as its next version first."""
        with self._factory() as db, db.begin():
            stored = get_journey(db, journey_id, version)
            check, line_version = validate_journey(db, stored.journey)
            if not check.valid:
                raise ConflictError(
                    f"journey {journey_id} no longer valid on line version {line_version}"
                )
            if self.planner is None:
                return stored, check, line_version, None
            top_speed = line_top_speed_mps(db, stored.journey.line_id)
            planned = self.planner.plan(vehicle_id, stored.journey, check, top_speed)
            if planned.delay_s > 0.0:
                stored = create_journey(
                    db, planned.journey, created_by=f"{user.username} (planner)"
                )
                check, line_version = validate_journey(db, stored.journey)
        return stored, check, line_version, planned
