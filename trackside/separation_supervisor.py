"""The RBC's separation of trains on a shared line: MAs that end behind the train ahead.

:class:`SeparationSupervisor` sits between whoever asks for an MA (the operator's API, a
scenario, a dispatcher) and :class:`~trackside.rbc.RbcEmulator`. Each request is the route's
authority: how far the line is set for the train. What the RBC grants is that authority cut at
the train's limit in the moving block (:class:`~trackside.separation.MovingBlock`: the min safe
rear end of the train ahead, less the margin). Then, on every position report of a train on
the line:

- a train held short of its route's authority has its MA **extended** as the train ahead moves
  on: by at least ``extension_step_m`` at a time (an MA message for every metre the leader
  runs would flood the radio link), or up to the route's authority when that is in reach;
- a train whose granted EoA now lies beyond its limit (a train placed ahead of it after its MA
  was granted, a leader's interval that widened) has its MA **shortened** to the limit, with
  the ETCS shortening procedure (:meth:`~trackside.rbc.RbcEmulator.shorten`); when the limit
  lies at or behind the train's own front end, the MA is **revoked**: the onboard stops at once.

An EoA cut by a train carries that train's min safe rear end as its danger point (D_DP = the
margin): what the onboard supervises its release speed and its emergency-brake curve against.

A train the moving block does not know (no report yet) is granted nothing: a request for it
raises :class:`~trackside.errors.VehicleNotPlacedError`.

All positions are the line's chainages. On a ring, an EoA may be unwrapped beyond the lap's
end (as the RBC's MAs are): reaches are compared as distances from the train's front end,
less than one lap, and the granted EoA is given in the request's own frame.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable

from protocol import messages as m
from trackside.errors import EndOfAuthorityBehindVehicleError, VehicleNotPlacedError
from trackside.rbc import MovementAuthorityIssue, RbcEmulator
from trackside.separation import MovingBlock, TrainExtent, extent_from_report

__all__ = ["SAME_EOA_M", "SeparationSupervisor"]

_log = logging.getLogger(__name__)

SAME_EOA_M = 1e-3
"""Two EoAs closer than this [m] are the same: a limit recomputed round a ring differs from
the granted one by rounding alone, and must not shorten (or revoke) the MA of a train standing
at it."""


class SeparationSupervisor:
    """Grants each train its route's authority up to the train ahead, and keeps it so.

    Parameters
    ----------
    rbc
        The RBC the MAs are issued, extended, shortened and revoked through.
    block
        The trains on the lines, fed by :meth:`on_report`.
    extension_step_m
        The least an MA is extended by while the train is held short of its route [m].
    lengths
        A train's length [m] when :meth:`register` was not told it (the service: from the
        train's session handshake); None when unknown, and the train's reports are ignored.
    """

    def __init__(
        self,
        rbc: RbcEmulator,
        block: MovingBlock,
        *,
        extension_step_m: float = 50.0,
        lengths: Callable[[str], float | None] | None = None,
    ) -> None:
        if not (math.isfinite(extension_step_m) and extension_step_m >= 0.0):
            raise ValueError(f"extension step {extension_step_m} m must be finite and ≥ 0")
        self.rbc = rbc
        self.block = block
        self.extension_step_m = extension_step_m
        self._lock = threading.Lock()
        self._routes: dict[str, MovementAuthorityIssue] = {}
        self._lengths_m: dict[str, float] = {}
        self._lengths = lengths

    # -- the trains ---------------------------------------------------------------------------

    def register(self, vehicle_id: str, *, train_length_m: float) -> None:
        """A train's length [m], from its session's handshake; its reports then place it."""
        if not (math.isfinite(train_length_m) and train_length_m > 0.0):
            raise ValueError(f"train length {train_length_m} m must be finite and positive")
        with self._lock:
            self._lengths_m[vehicle_id] = train_length_m

    def on_report(self, report: m.StatusReport, received_at_s: float) -> None:
        """A train's position report: place it, then bring every MA on its line in line with
        the limits (extend, shorten or revoke). Reports of unregistered trains are ignored."""
        with self._lock:
            length = self._lengths_m.get(report.vehicle_id)
            if length is None and self._lengths is not None:
                length = self._lengths(report.vehicle_id)
            if length is None:
                return
            self.block.update(
                extent_from_report(report, train_length_m=length, received_at_s=received_at_s)
            )
            for extent in self.block.trains(report.line_id):
                self._follow(extent.vehicle_id)

    def withdraw(self, vehicle_id: str) -> None:
        """The train leaves the line (its session ended, the operator took it off): it bounds
        no train behind it, and its route is forgotten."""
        with self._lock:
            self.block.remove(vehicle_id)
            self._routes.pop(vehicle_id, None)

    def forget_route(self, vehicle_id: str) -> None:
        """The train's MA was revoked: nothing extends it again (the train stays on the line
        and goes on bounding the train behind it)."""
        with self._lock:
            self._routes.pop(vehicle_id, None)

    # -- the MAs ------------------------------------------------------------------------------

    def request(self, vehicle_id: str, route: MovementAuthorityIssue) -> m.MovementAuthorityMessage:
        """Set the train's route authority and issue its MA, cut at the train ahead.

        Raises
        ------
        VehicleNotPlacedError
            If no report has placed the train.
        MovementAuthorityRefusedError
            If the RBC refuses the MA (see :meth:`~trackside.rbc.RbcEmulator.issue`), or if the
            train ahead leaves it no room.
        """
        with self._lock:
            if self.block.extent(vehicle_id) is None:
                raise VehicleNotPlacedError(
                    f"{vehicle_id} has not reported its position: the RBC cannot place it"
                )
            granted = self._granted_end(vehicle_id, route)
            if granted is None:
                message = self.rbc.issue(vehicle_id, route)
            else:
                message = self.rbc.issue(vehicle_id, route.model_copy(update=granted.model_dump()))
            self._routes[vehicle_id] = route
            return message

    # -- internals ----------------------------------------------------------------------------

    def _granted_end(
        self, vehicle_id: str, route: m.MovementAuthorityExtent | MovementAuthorityIssue
    ) -> m.MovementAuthorityEnd | None:
        """The end the train may have of ``route``: None for the route's own, else the EoA cut
        the margin behind the train ahead, its danger point at that train's rear end."""
        extent = self.block.extent(vehicle_id)
        gap = self.block.gap_m(vehicle_id)
        if extent is None or math.isinf(gap):
            return None
        allowed = gap - self.block.margin_m
        wanted = self._reach_m(extent, route.end_of_authority_m)
        if wanted <= allowed:
            return None
        return m.MovementAuthorityEnd(
            end_of_authority_m=route.end_of_authority_m - (wanted - allowed),
            danger_point_m=self.block.margin_m,
        )

    def _follow(self, vehicle_id: str) -> None:
        """Extend, shorten or revoke the train's MA to its limit (with the lock held)."""
        route = self._routes.get(vehicle_id)
        current = self.rbc.current(vehicle_id)
        if route is None or current is None or current.authority is None:
            return
        granted_m = current.authority.end_of_authority_m
        cut = self._granted_end(vehicle_id, route)
        target = m.MovementAuthorityEnd(**_end_fields(route)) if cut is None else cut
        extent = self.block.extent(vehicle_id)
        assert extent is not None  # placed: its route was granted
        gain_m = self._reach_m(extent, target.end_of_authority_m) - self._reach_m(extent, granted_m)
        if gain_m > SAME_EOA_M:
            if cut is None or gain_m >= self.extension_step_m:
                self.rbc.extend(vehicle_id, target)
            return
        if gain_m < -SAME_EOA_M:
            self._shorten(vehicle_id, target)

    def _reach_m(self, extent: TrainExtent, end_of_authority_m: float) -> float:
        """How far an EoA lies ahead of the train's max safe front end [m], measured from its
        min safe rear end: a train standing at its EoA may report a front end a little beyond
        it, and on a ring that EoA is then just behind the front (negative), not a lap ahead."""
        from_rear = self.block.ahead_m(extent.line_id, extent.rear_m, end_of_authority_m)
        return from_rear - (extent.front_m - extent.rear_m)

    def _shorten(self, vehicle_id: str, target: m.MovementAuthorityEnd) -> None:
        try:
            self.rbc.shorten(vehicle_id, target)
        except EndOfAuthorityBehindVehicleError:
            # No room left before the train ahead: the train must stop now.
            _log.warning("%s: no room behind the train ahead, MA revoked", vehicle_id)
            self.rbc.revoke(vehicle_id)
            self._routes.pop(vehicle_id, None)


def _end_fields(route: MovementAuthorityIssue) -> dict[str, object]:
    """The end fields of a route (its EoA, danger point, overlap and their timers)."""
    return {name: getattr(route, name) for name in m.MovementAuthorityEnd.model_fields}
