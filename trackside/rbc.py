"""The RBC emulator: ETCS Level 2 movement authorities (MA) for every vehicle, over Zenoh.

An RBC (radio block centre) grants each vehicle an MA up to an end of authority (EoA), moves that
end forward as the line ahead clears (extension) or back as it closes (shortening), and may
withdraw it (revocation). :class:`RbcEmulator` holds the current MA of every vehicle and numbers
every change (``ma_id``, +1 per change and vehicle, never reused). It publishes each change on
``ato/ts/rbc/{vehicle}/ma`` (reliable FIFO), answers ``ato/ts/rbc/{vehicle}/current_ma`` for an
onboard that starts up or lost the stream, and records the onboard's acknowledgements from
``ato/ob/{vehicle}/ma_ack``. Without a Zenoh session it only calls its listeners, which is what a
lockstep test needs.

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
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Self

import zenoh
from pydantic import Field

from protocol import TransportError, TypedPublisher, TypedQueryable, TypedSubscriber
from protocol import messages as m
from protocol.registry import (
    MOVEMENT_AUTHORITY,
    MOVEMENT_AUTHORITY_ACK,
    MOVEMENT_AUTHORITY_CURRENT,
    SPEED_RESTRICTION,
)
from trackside.errors import (
    EndOfAuthorityBehindVehicleError,
    MovementAuthorityRefusedError,
    NoMovementAuthorityError,
    RbcPublicationError,
)
from trackside.rbc_rules import (
    LineInfo,
    LineInfoLookup,
    as_end,
    built,
    check_on_line,
    check_vehicle_id,
    cut_sections,
    extent_from,
    rebuilt,
    unwrapped,
)

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
PositionLookup = Callable[[str], m.StatusReport | None]
"""The vehicle's latest status report, ``None`` when none is known (or the vehicle is gone)."""
MaListener = Callable[[m.MovementAuthorityMessage], None]

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
    """

    def __init__(
        self,
        *,
        clock: Clock,
        session: zenoh.Session | None = None,
        line_info: LineInfoLookup | None = None,
        positions: PositionLookup | None = None,
        margin_m: float = 0.0,
    ) -> None:
        if not (math.isfinite(margin_m) and margin_m >= 0.0):
            raise ValueError(f"margin {margin_m} m must be finite and ≥ 0")
        self.clock = clock
        self._session = session
        self._line_info = line_info
        self._positions = positions
        self._margin_m = margin_m
        # Changes hold _change_lock across publication (wire order = ma_id order); readers,
        # such as the queryable on Zenoh's thread, only ever take the short _state_lock.
        self._change_lock = threading.Lock()
        self._state_lock = threading.Lock()
        self._current: dict[str, m.MovementAuthorityMessage] = {}
        self._last_ma_id: dict[str, int] = {}
        self._acknowledgements: dict[str, m.MovementAuthorityAck] = {}
        self._listeners: list[MaListener] = []
        self._publishers: dict[str, TypedPublisher[m.MovementAuthorityMessage]] = {}
        self._tsr_publishers: dict[str, TypedPublisher[m.SpeedRestrictionMessage]] = {}
        self._queryable: TypedQueryable[m.MovementAuthorityRequest] | None = None
        self._acks: TypedSubscriber[m.MovementAuthorityAck] | None = None
        if session is not None:
            self._queryable = TypedQueryable(
                session, MOVEMENT_AUTHORITY_CURRENT, self._answer_current
            )
            try:
                self._acks = TypedSubscriber(
                    session, MOVEMENT_AUTHORITY_ACK, on_message=self._on_acknowledgement
                )
            except Exception:
                self._queryable.close()
                raise

    # -- reading ------------------------------------------------------------------------------

    def current(self, vehicle_id: str) -> m.MovementAuthorityMessage | None:
        """The vehicle's MA in force (issued, extended or shortened); ``None`` if none."""
        with self._state_lock:
            return self._current.get(vehicle_id)

    def last_ma_id(self, vehicle_id: str) -> int:
        """The id of the last MA message sent to the vehicle (revocations too); 0 if none."""
        with self._state_lock:
            return self._last_ma_id.get(vehicle_id, 0)

    def acknowledgement(self, vehicle_id: str) -> m.MovementAuthorityAck | None:
        """The vehicle's latest acknowledgement of one of its MAs, if any arrived."""
        with self._state_lock:
            return self._acknowledgements.get(vehicle_id)

    def vehicle_ids(self) -> list[str]:
        """The vehicles that were ever sent an MA."""
        with self._state_lock:
            return sorted(self._last_ma_id)

    def add_listener(self, listener: MaListener) -> None:
        """Call ``listener(message)`` after each change, in ``ma_id`` order, on its thread."""
        with self._state_lock:
            self._listeners.append(listener)

    def remove_listener(self, listener: MaListener) -> None:
        with self._state_lock:
            if listener in self._listeners:
                self._listeners.remove(listener)

    # -- changes ------------------------------------------------------------------------------

    def issue(self, vehicle_id: str, request: MovementAuthorityIssue) -> m.MovementAuthorityMessage:
        """Grant the vehicle a new MA, replacing any it holds."""
        check_vehicle_id(vehicle_id)
        with self._change_lock:
            version, info = self._line_version(request.line_id, request.line_version)
            extent = built(lambda: request.extent())
            check_on_line(extent, request.line_id, info)
            self._check_ahead_of_vehicle(vehicle_id, request.line_id, extent, info)
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
            old = _authority(current)
            if not new_end.end_of_authority_m > old.end_of_authority_m:
                raise MovementAuthorityRefusedError(
                    f"an extension must move the EoA forward: {new_end.end_of_authority_m:g} m "
                    f"is not beyond the current EoA at {old.end_of_authority_m:g} m"
                )
            sections = old.sections
            if sections:
                added_m = new_end.end_of_authority_m - old.end_of_authority_m
                sections = (*sections, m.MovementAuthoritySection(length_m=added_m))
            extent = built(lambda: extent_from(old.start_m, new_end, sections, None))
            check_on_line(extent, current.line_id, self._info(current.line_id))
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
            eoa_m = new_end.end_of_authority_m
            if not eoa_m < old.end_of_authority_m:
                raise MovementAuthorityRefusedError(
                    f"a shortening must move the EoA back: {eoa_m:g} m is not before the current "
                    f"EoA at {old.end_of_authority_m:g} m"
                )
            if not eoa_m > old.start_m:
                raise MovementAuthorityRefusedError(
                    f"a shortened EoA must stay beyond the MA's start at {old.start_m:g} m, "
                    f"not {eoa_m:g} m; revoke the MA instead"
                )
            sections = cut_sections(old.sections, eoa_m - old.start_m)
            extent = built(
                lambda: extent_from(old.start_m, new_end, sections, old.track_description_m)
            )
            info = self._info(current.line_id)
            check_on_line(extent, current.line_id, info)
            self._check_ahead_of_vehicle(
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
        if message.vehicle_id != vehicle_id:
            raise MovementAuthorityRefusedError(
                f"TSR for {message.vehicle_id} sent to {vehicle_id}"
            )
        info = self._info(message.line_id)
        if self._line_info is not None and info is None:
            raise MovementAuthorityRefusedError(f"the trackside holds no line {message.line_id!r}")
        if info is not None and message.end_m > info.length_m:
            raise MovementAuthorityRefusedError(
                f"TSR {message.restriction_id!r}: {message.start_m:g}..{message.end_m:g} m is"
                f" not on line {message.line_id!r} (0..{info.length_m:g} m)"
            )
        if self._session is None:
            return
        with self._change_lock, _publication():
            publisher = self._tsr_publishers.get(vehicle_id)
            if publisher is None:
                publisher = TypedPublisher(self._session, SPEED_RESTRICTION, vehicle=vehicle_id)
                self._tsr_publishers[vehicle_id] = publisher
            publisher.put(message)

    def close(self) -> None:
        """Stop answering and publishing; the MAs held are forgotten with the object."""
        with self._change_lock:
            for publisher in self._publishers.values():
                publisher.close()
            self._publishers.clear()
            for tsr_publisher in self._tsr_publishers.values():
                tsr_publisher.close()
            self._tsr_publishers.clear()
        if self._acks is not None:
            self._acks.close()
        if self._queryable is not None:
            self._queryable.close()

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

    def _info(self, line_id: str) -> LineInfo | None:
        return None if self._line_info is None else self._line_info(line_id)

    def _line_version(self, line_id: str, version: str | None) -> tuple[str, LineInfo | None]:
        info = self._info(line_id)
        if self._line_info is not None and info is None:
            raise MovementAuthorityRefusedError(f"the trackside holds no line {line_id!r}")
        if version is None:
            if info is None:
                raise MovementAuthorityRefusedError(
                    f"the track-data version of line {line_id!r} is not known here: "
                    "give line_version"
                )
            return info.version, info
        if info is not None and version != info.version:
            raise MovementAuthorityRefusedError(
                f"line {line_id!r} is at version {info.version}, not {version}"
            )
        return version, info

    def _check_ahead_of_vehicle(
        self,
        vehicle_id: str,
        line_id: str,
        extent: m.MovementAuthorityExtent,
        info: LineInfo | None,
        *,
        reach_m: float | None = None,
    ) -> None:
        report = None if self._positions is None else self._positions(vehicle_id)
        if report is None or report.line_id != line_id:
            return
        far_m = extent.end_of_authority_m if reach_m is None else reach_m
        position_m = unwrapped(report.position_m, extent.start_m, far_m, info)
        eoa_m = extent.end_of_authority_m
        if eoa_m <= position_m + self._margin_m:
            margin = f" plus the {self._margin_m:g} m margin" if self._margin_m else ""
            raise EndOfAuthorityBehindVehicleError(
                f"the EoA at {eoa_m:g} m would lie at or behind {vehicle_id}'s front end, last "
                f"reported at {report.position_m:g} m{margin}",
                end_of_authority_m=eoa_m,
                position_m=report.position_m,
            )

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
        self._publish(message)
        with self._state_lock:
            self._last_ma_id[vehicle_id] = message.ma_id
            if extent is None:
                self._current.pop(vehicle_id, None)
            else:
                self._current[vehicle_id] = message
            listeners = list(self._listeners)
        for listener in listeners:
            try:
                listener(message)
            except Exception:  # a listener's bug must not undo a change already sent
                _log.exception("MA listener failed on %s ma_id %d", vehicle_id, message.ma_id)
        _log.info(
            "MA %s for %s: ma_id %d, EoA %s",
            change.value,
            vehicle_id,
            message.ma_id,
            "none" if extent is None else f"{extent.end_of_authority_m:g} m",
        )
        return message

    def _publish(self, message: m.MovementAuthorityMessage) -> None:
        if self._session is None:
            return
        vehicle_id = message.vehicle_id
        with _publication():
            publisher = self._publishers.get(vehicle_id)
            if publisher is None:
                publisher = TypedPublisher(self._session, MOVEMENT_AUTHORITY, vehicle=vehicle_id)
                self._publishers[vehicle_id] = publisher
            publisher.put(message)

    def _answer_current(
        self, chunks: dict[str, str], request: m.MovementAuthorityRequest
    ) -> m.MovementAuthorityReply:
        vehicle_id = chunks["vehicle"]
        if request.vehicle_id != vehicle_id:
            raise ValueError(f"request for {request.vehicle_id} sent on {vehicle_id}'s key")
        return m.MovementAuthorityReply(
            vehicle_id=vehicle_id, movement_authority=self.current(vehicle_id)
        )

    def _on_acknowledgement(self, key: str, ack: m.MovementAuthorityAck) -> None:
        vehicle_id = MOVEMENT_AUTHORITY_ACK.parse(key)["vehicle"]
        if ack.vehicle_id != vehicle_id:
            _log.warning("dropped an MA ack of %s sent on %s's key", ack.vehicle_id, vehicle_id)
            return
        with self._state_lock:
            if ack.ma_id > self._last_ma_id.get(vehicle_id, 0):
                _log.warning("dropped %s's ack of ma_id %d, never sent", vehicle_id, ack.ma_id)
                return
            previous = self._acknowledgements.get(vehicle_id)
            if previous is None or ack.ma_id >= previous.ma_id:
                self._acknowledgements[vehicle_id] = ack


def _authority(message: m.MovementAuthorityMessage) -> m.MovementAuthorityExtent:
    if message.authority is None:  # pragma: no cover - revoked MAs are not stored
        raise NoMovementAuthorityError(f"the MA of {message.vehicle_id} is revoked")
    return message.authority


@contextmanager
def _publication() -> Iterator[None]:
    """Zenoh's failure to publish, as the RBC's own error (nothing was changed)."""
    try:
        yield
    except TransportError as exc:
        raise RbcPublicationError(f"the MA could not be published, nothing changed: {exc}") from exc
