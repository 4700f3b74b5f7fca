"""The RBC's state in the database: what it decided survives a restart of the trackside.

Each vehicle's ``ma_id`` counter and MA in force (table ``rbc_movement_authorities``) and its
TSRs in force (``rbc_speed_restrictions``) are written in the same transaction as the change is
sent: the row is written, the message published, and only then the transaction committed, so
that a change that could not be published is not kept, and one that could not be kept is not
sent (the publication happens before the commit: a commit that fails after a publication
leaves the vehicle one change ahead of the database, logged; the next change overwrites it).
:meth:`RbcPersistence.load` gives it all back at start-up, to
:meth:`trackside.rbc_store.MovementAuthorityStore.restore`.

Messages are kept as their JSON without the session's seal (``freshness``): they are sealed
again each time they are sent.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime

from sqlalchemy import delete, select
from sqlalchemy.orm import Session, sessionmaker

from protocol import messages as m
from trackside.models import RbcAuthorityRow, RbcRestrictionRow

__all__ = ["RbcPersistence", "RbcState"]


@dataclass
class RbcState:
    """What the RBC kept: counters, MAs in force and TSRs in force, by vehicle."""

    last_ma_ids: dict[str, int] = field(default_factory=dict)
    current: dict[str, m.MovementAuthorityMessage] = field(default_factory=dict)
    restrictions: dict[str, dict[str, m.SpeedRestrictionMessage]] = field(default_factory=dict)


class RbcPersistence:
    """Reads and writes the RBC's tables through ``factory``."""

    def __init__(self, factory: sessionmaker[Session]) -> None:
        self._factory = factory

    def load(self) -> RbcState:
        """Everything kept, as messages."""
        state = RbcState()
        with self._factory() as db:
            for row in db.scalars(select(RbcAuthorityRow)):
                state.last_ma_ids[row.vehicle_id] = row.last_ma_id
                if row.message is not None:
                    message = m.MovementAuthorityMessage.model_validate_json(row.message)
                    state.current[row.vehicle_id] = message
            query = select(RbcRestrictionRow).order_by(RbcRestrictionRow.issued_at)
            for tsr in db.scalars(query):
                restriction = m.SpeedRestrictionMessage.model_validate_json(tsr.message)
                state.restrictions.setdefault(tsr.vehicle_id, {})[tsr.restriction_id] = restriction
        return state

    @contextmanager
    def recording_authority(self, message: m.MovementAuthorityMessage) -> Iterator[None]:
        """Write the MA change, run the block (its publication), then commit; an exception in
        the block rolls the write back."""
        with self._factory.begin() as db:
            row = db.get(RbcAuthorityRow, message.vehicle_id)
            if row is None:
                row = RbcAuthorityRow(vehicle_id=message.vehicle_id)
                db.add(row)
            row.last_ma_id = message.ma_id
            row.message = None if message.authority is None else _unsealed(message)
            row.updated_at = datetime.now(UTC)
            db.flush()
            yield

    @contextmanager
    def recording_restriction(self, message: m.SpeedRestrictionMessage) -> Iterator[None]:
        """Write the TSR (or delete it when revoked), run the block, then commit."""
        with self._factory.begin() as db:
            db.execute(
                delete(RbcRestrictionRow).where(
                    RbcRestrictionRow.vehicle_id == message.vehicle_id,
                    RbcRestrictionRow.restriction_id == message.restriction_id,
                )
            )
            if message.speed_mps is not None:
                db.add(
                    RbcRestrictionRow(
                        vehicle_id=message.vehicle_id,
                        restriction_id=message.restriction_id,
                        message=_unsealed(message),
                        issued_at=datetime.now(UTC),
                    )
                )
            db.flush()
            yield


def _unsealed(message: m.MovementAuthorityMessage | m.SpeedRestrictionMessage) -> str:
    return message.model_copy(update={"freshness": None}).model_dump_json()
