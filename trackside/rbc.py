"""The RBC emulator: ETCS Level 2 movement authorities (MA) for every vehicle, over Zenoh.

An RBC (radio block centre) grants each vehicle an MA up to an end of authority (EoA), moves that
end forward as the line ahead clears (extension) or back as it closes (shortening), and may
withdraw it (revocation). :class:`RbcEmulator` holds the current MA of every vehicle and numbers
every change (``ma_id``, +1 per change and vehicle, never reused). It publishes each change on
``ato/ts/rbc/{vehicle}/ma`` (reliable FIFO), answers ``ato/ts/rbc/{vehicle}/current_ma`` (the
MA and the TSRs in force) for an onboard that starts up or opens a new session, and records the
onboard's acknowledgements from ``ato/ob/{vehicle}/ma_ack``. Without a Zenoh session it only
calls its listeners, which is what a lockstep test needs.

Durable: with a database (``persistence``), the counters, the MAs and the TSRs in force are
written as they are sent and restored when the emulator starts (:mod:`trackside.rbc_persistence`),
so a restarted trackside goes on numbering, extending and revoking where it left off.

Nothing half-done: a change is checked, then published, then stored; a refusal
(:class:`~trackside.errors.MovementAuthorityRefusedError`) or a failed publication
(:class:`~trackside.errors.RbcPublicationError`, from Zenoh's :class:`protocol.TransportError`)
leaves the MA and the counter as they were. Changes are serialised, so the wire carries them in
``ma_id`` order.

Positions. ``positions`` gives the vehicle's last status report (the bridge's, in the service).
An EoA at or behind the reported front end (plus ``margin_m``) is refused with
:class:`~trackside.errors.EndOfAuthorityBehindVehicleError`: the onboard would trip at once.
``line_info`` gives each line's current version and geometry: an MA must stay on an open line,
and on a ring line it must be shorter than one lap, with the reported position unwrapped to the
location nearest the MA.

Time comes from the ``clock`` given [s]: the simulated clock in lockstep, the seconds since
start-up in the service. Scripts that drive the emulator: :mod:`trackside.rbc_scenario`.

:class:`RbcEmulator` orchestrates; its parts are the rules of an MA (:mod:`trackside.rbc_rules`),
the checks against lines and positions (:mod:`trackside.rbc_checks`), the store of MAs,
counters and acknowledgements (:mod:`trackside.rbc_store`) and the Zenoh side
(:mod:`trackside.rbc_link`).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from typing import Self

import zenoh
from pydantic import Field

from protocol import messages as m
from trackside.errors import NoMovementAuthorityError
from trackside.rbc_checks import MovementAuthorityChecks, PositionLookup
from trackside.rbc_link import RbcZenohLink, Seal
from trackside.rbc_persistence import RbcPersistence
from trackside.rbc_rules import (
    LineInfo,
    LineInfoLookup,
    as_end,
    built,
    check_on_line,
    check_vehicle_id,
    extended,
    rebuilt,
    shortened,
)
from trackside.rbc_store import MaListener, MovementAuthorityStore

__all__ = [
    "Clock",
    "LineInfo",
    "LineInfoLookup",
    "MovementAuthorityIssue",
    "PositionLookup",
    "RbcEmulator",
]

Clock = Callable[[], float]
"""The RBC's time [s]."""

_log = logging.getLogger(__name__)


class MovementAuthorityIssue(m.MovementAuthorityExtent):
    """An MA to issue: where it reaches, on which line, for which track-data version."""

    line_id: str = Field(min_length=1, max_length=64, description="Line the MA is on")
    line_version: str | None = Field(
        default=None,
        min_length=1,
        max_length=128,
        description="Track-data version; by default the line's current one",
    )

    def extent(self) -> m.MovementAuthorityExtent:
        """The MA's extent alone, as it goes on the wire."""
        return rebuilt(m.MovementAuthorityExtent, self)


class RbcEmulator:
    """The trackside's RBC: the current MA of every vehicle, published on each change.

    Parameters
    ----------
    clock
        The RBC's time [s]; stamped on every MA as ``issued_at_s``.
    session
        The Zenoh session to publish on and answer queries from; ``None`` for listeners only.
    line_info
        Each line's current version and extent; without it, MAs must name their line version
        and are not checked against the line.
    positions
        Each vehicle's latest status report; without it, EoAs are not checked against positions.
    margin_m
        An EoA must lie more than this far [m] ahead of the reported front end.
    seal
        Seals each message for its vehicle's session (:meth:`trackside.bridge.ZenohBridge.seal`).
    persistence
        Where the MAs, counters and TSRs are kept across restarts; none: in memory only.
    """

    def __init__(
        self,
        *,
        clock: Clock,
        session: zenoh.Session | None = None,
        line_info: LineInfoLookup | None = None,
        positions: PositionLookup | None = None,
        margin_m: float = 0.0,
        seal: Seal | None = None,
        persistence: RbcPersistence | None = None,
    ) -> None:
        self._checks = MovementAuthorityChecks(
            line_info=line_info, positions=positions, margin_m=margin_m
        )
        self.clock = clock
        # Changes hold _change_lock across publication (wire order = ma_id order); readers,
        # such as the queryable on Zenoh's thread, only ever take the store's short lock.
        self._change_lock = threading.Lock()
        self._store = MovementAuthorityStore()
        self._persistence = persistence
        if persistence is not None:
            kept = persistence.load()
            self._store.restore(kept.last_ma_ids, kept.current, kept.restrictions)
        self._link = None if session is None else RbcZenohLink(session, self._store, seal)

    # -- reading ------------------------------------------------------------------------------

    def current(self, vehicle_id: str) -> m.MovementAuthorityMessage | None:
        """The vehicle's MA in force (issued, extended or shortened); ``None`` if none."""
        return self._store.current(vehicle_id)

    def last_ma_id(self, vehicle_id: str) -> int:
        """The id of the last MA message sent to the vehicle (revocations too); 0 if none."""
        return self._store.last_ma_id(vehicle_id)

    def acknowledgement(self, vehicle_id: str) -> m.MovementAuthorityAck | None:
        """The vehicle's latest acknowledgement of one of its MAs, if any arrived."""
        return self._store.acknowledgement(vehicle_id)

    def vehicle_ids(self) -> list[str]:
        """The vehicles that were ever sent an MA."""
        return self._store.vehicle_ids()

    def restrictions(self, vehicle_id: str) -> tuple[m.SpeedRestrictionMessage, ...]:
        """The TSRs in force for the vehicle, in the order they were put in force."""
        return self._store.restrictions(vehicle_id)

    def add_listener(self, listener: MaListener) -> None:
        """Call ``listener(message)`` after each change, in ``ma_id`` order, on its thread."""
        self._store.add_listener(listener)

    def remove_listener(self, listener: MaListener) -> None:
        self._store.remove_listener(listener)

    # -- changes ------------------------------------------------------------------------------

    def issue(self, vehicle_id: str, request: MovementAuthorityIssue) -> m.MovementAuthorityMessage:
        """Grant the vehicle a new MA, replacing any it holds."""
        check_vehicle_id(vehicle_id)
        with self._change_lock:
            version, info = self._checks.line_version(request.line_id, request.line_version)
            extent = built(lambda: request.extent())
            check_on_line(extent, request.line_id, info)
            self._checks.check_ahead_of_vehicle(vehicle_id, request.line_id, extent, info)
            return self._commit(
                vehicle_id, m.MovementAuthorityChange.ISSUED, request.line_id, version, extent
            )

    def extend(
        self, vehicle_id: str, end: m.MovementAuthorityEnd | float
    ) -> m.MovementAuthorityMessage:
        """Move the EoA forward to ``end`` (with the new end's danger point, overlap, timers).

        Sections, if the MA has them, gain one up to the new EoA, without a timer.
        """
        new_end = as_end(end)
        with self._change_lock:
            current = self._require(vehicle_id)
            extent = extended(_authority(current), new_end)
            check_on_line(extent, current.line_id, self._checks.info(current.line_id))
            return self._commit(
                vehicle_id,
                m.MovementAuthorityChange.EXTENDED,
                current.line_id,
                current.line_version,
                extent,
            )

    def shorten(
        self, vehicle_id: str, end: m.MovementAuthorityEnd | float
    ) -> m.MovementAuthorityMessage:
        """Move the EoA back to ``end``, which must stay ahead of the vehicle's reported front end.

        Sections beyond the new EoA are dropped and the one it falls in is cut there.
        """
        new_end = as_end(end)
        with self._change_lock:
            current = self._require(vehicle_id)
            old = _authority(current)
            extent = shortened(old, new_end)
            info = self._checks.info(current.line_id)
            check_on_line(extent, current.line_id, info)
            self._checks.check_ahead_of_vehicle(
                vehicle_id, current.line_id, extent, info, reach_m=old.end_of_authority_m
            )
            return self._commit(
                vehicle_id,
                m.MovementAuthorityChange.SHORTENED,
                current.line_id,
                current.line_version,
                extent,
            )

    def revoke(self, vehicle_id: str) -> m.MovementAuthorityMessage:
        """Withdraw the vehicle's MA (the onboard applies it as an emergency stop)."""
        with self._change_lock:
            current = self._require(vehicle_id)
            return self._commit(
                vehicle_id,
                m.MovementAuthorityChange.REVOKED,
                current.line_id,
                current.line_version,
                None,
            )

    # -- temporary speed restrictions ---------------------------------------------------------

    def restrict_speed(self, vehicle_id: str, message: m.SpeedRestrictionMessage) -> None:
        """Send a TSR (or its revocation, ``speed_mps`` None) to the vehicle.

        Raises
        ------
        MovementAuthorityRefusedError
            If the trackside does not hold the line, or the range is not on it.
        RbcPublicationError
            If it could not be published.
        """
        self._checks.check_speed_restriction(vehicle_id, message)
        link = self._link
        with self._change_lock:
            self._send(
                message,
                lambda: _publish_speed_restriction(link, vehicle_id, message),
                lambda: self._store.record_restriction(message),
            )

    def close(self) -> None:
        """Stop answering and publishing; the MAs held are forgotten with the object."""
        link = self._link
        with self._change_lock:  # a change under way finishes first
            if link is not None:
                link.close_publishers()
        if link is not None:
            link.close_subscriptions()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    # -- internals ----------------------------------------------------------------------------

    def _require(self, vehicle_id: str) -> m.MovementAuthorityMessage:
        current = self.current(vehicle_id)
        if current is None:
            raise NoMovementAuthorityError(f"the RBC holds no movement authority for {vehicle_id}")
        return current

    def _commit(
        self,
        vehicle_id: str,
        change: m.MovementAuthorityChange,
        line_id: str,
        line_version: str,
        extent: m.MovementAuthorityExtent | None,
    ) -> m.MovementAuthorityMessage:
        """Number, publish, then store one change; called with the change lock held."""
        message = built(
            lambda: m.MovementAuthorityMessage(
                vehicle_id=vehicle_id,
                ma_id=self.last_ma_id(vehicle_id) + 1,
                change=change,
                issued_at_s=self.clock(),
                line_id=line_id,
                line_version=line_version,
                authority=extent,
            )
        )
        link = self._link
        self._send(
            message,
            lambda: _publish_movement_authority(link, message),
            lambda: self._store.record(message),
        )
        _log.info(
            "MA %s for %s: ma_id %d, EoA %s",
            change.value,
            vehicle_id,
            message.ma_id,
            "none" if extent is None else f"{extent.end_of_authority_m:g} m",
        )
        return message

    def _send(
        self,
        message: m.MovementAuthorityMessage | m.SpeedRestrictionMessage,
        publish: Callable[[], object],
        record: Callable[[], None],
    ) -> None:
        """Publish while the change is written to the database, and record it in memory once
        published: a failed publication keeps nothing; a commit that fails after the
        publication still records it in memory (the vehicle has it), and raises."""
        published = False
        try:
            with self._recording(message):
                publish()
                published = True
        finally:
            if published:
                record()

    def _recording(
        self, message: m.MovementAuthorityMessage | m.SpeedRestrictionMessage
    ) -> AbstractContextManager[None]:
        """Kept in the database around its publication (nothing kept without persistence)."""
        if self._persistence is None:
            return nullcontext()
        if isinstance(message, m.MovementAuthorityMessage):
            return self._persistence.recording_authority(message)
        return self._persistence.recording_restriction(message)


def _authority(message: m.MovementAuthorityMessage) -> m.MovementAuthorityExtent:
    if message.authority is None:  # pragma: no cover - revoked MAs are not stored
        raise NoMovementAuthorityError(f"the MA of {message.vehicle_id} is revoked")
    return message.authority


def _publish_movement_authority(
    link: RbcZenohLink | None, message: m.MovementAuthorityMessage
) -> None:
    if link is not None:
        link.publish_movement_authority(message)


def _publish_speed_restriction(
    link: RbcZenohLink | None, vehicle_id: str, message: m.SpeedRestrictionMessage
) -> None:
    if link is not None:
        link.publish_speed_restriction(vehicle_id, message)
