"""The simulated operator: answers the Vital Control's operator requests of chosen vehicles.

Unattended runs need someone to confirm the EB rearm at power-up and to acknowledge vigilance;
this operator does it, for the vehicles it is configured for and no others, once a reaction
delay has passed in the vehicle's own simulated time since it first saw the request. Each answer
is a real ``COMMAND`` sent with ``issued_by="simulated-operator"`` and audited under that name.

Two ways to drive it (``docs/trackside.md`` documents both):

- :meth:`SimulatedOperator.step` looks at one status report and sends what is due without
  waiting: the acknowledgement arrives later on Zenoh's thread. A lockstep runner calls it
  between slices of simulated time and may wait for :meth:`SimulatedOperator.outstanding` to
  reach zero before advancing, so that the confirmation reaches the vehicle at a tick fixed by
  simulated time.
- :class:`SimulatedOperatorThread` calls ``step`` on the latest status of each configured vehicle
  at a fixed wall-clock period; the service runs one when ``ATO_SIMULATED_OPERATORS`` is set.
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from protocol import ProtocolError
from protocol import messages as m

__all__ = [
    "DEFAULT_KINDS",
    "SIMULATED_OPERATOR",
    "OperatorAnswer",
    "SimulatedOperator",
    "SimulatedOperatorThread",
]

_log = logging.getLogger(__name__)

SIMULATED_OPERATOR = "simulated-operator"
"""The name its commands are issued and audited under."""
DEFAULT_KINDS = (m.OperatorRequestKind.VIGILANCE, m.OperatorRequestKind.EB_REARM)
"""What it confirms unless told otherwise; ETCS isolation and insertion change the train's
protection, so they are confirmed only when configured."""

CommandSender = Callable[[m.Command, Callable[[m.CommandAck | None], None]], None]
"""Sends a command without waiting and calls back once, with its acknowledgement or with None
when none came (the bridge's ``command_async`` with its timeout bound)."""
_RequestKey = tuple[str, m.OperatorRequestKind, int, float]


@dataclass(frozen=True)
class OperatorAnswer:
    """One confirmation sent and what came of it: the ack, or None when the query timed out."""

    command: m.Command
    ack: m.CommandAck | None


class SimulatedOperator:
    """Confirms the operator requests of ``vehicles`` (see the module docstring)."""

    def __init__(
        self,
        send: CommandSender,
        vehicles: Iterable[str],
        *,
        reaction_s: float = 0.5,
        kinds: Iterable[m.OperatorRequestKind] = DEFAULT_KINDS,
        on_answer: Callable[[OperatorAnswer], None] | None = None,
        first_command_id: int = 1,
    ) -> None:
        self._send = send
        self.vehicles = frozenset(vehicles)
        self.reaction_s = reaction_s
        self.kinds = frozenset(kinds)
        self._on_answer = on_answer
        self._ids = itertools.count(first_command_id)
        self._lock = threading.Lock()
        self._seen_s: dict[_RequestKey, float] = {}
        self._sent: set[_RequestKey] = set()
        self._outstanding: dict[str, int] = {}
        self._answers: list[OperatorAnswer] = []

    def answers_for(self, vehicle_id: str) -> bool:
        return vehicle_id in self.vehicles

    def step(self, status: m.StatusReport) -> list[m.Command]:
        """Send, without waiting, each confirmation due at ``status.sim_time_s``: a pending,
        unconfirmed request of a configured kind, first seen at least ``reaction_s`` ago and not
        answered yet. Returns the commands sent (empty for a vehicle not configured)."""
        if status.vehicle_id not in self.vehicles or status.vital_control is None:
            return []
        now_s = status.sim_time_s
        due: list[tuple[m.Command, _RequestKey]] = []
        with self._lock:
            shown = {
                (status.vehicle_id, pending.kind, pending.number, pending.raised_s)
                for pending in status.vital_control.operator_requests
                if pending.kind in self.kinds and not pending.confirmed
            }
            self._forget_gone(status.vehicle_id, shown)
            for pending in status.vital_control.operator_requests:
                if pending.kind not in self.kinds or pending.confirmed:
                    continue
                key = (status.vehicle_id, pending.kind, pending.number, pending.raised_s)
                seen_s = self._seen_s.setdefault(key, now_s)
                if key in self._sent or now_s - seen_s < self.reaction_s:
                    continue
                self._sent.add(key)
                self._outstanding[status.vehicle_id] = (
                    self._outstanding.get(status.vehicle_id, 0) + 1
                )
                body = m.OperatorConfirmCommand(request=pending.kind, number=pending.number)
                command = m.Command(
                    vehicle_id=status.vehicle_id,
                    command_id=next(self._ids),
                    issued_by=SIMULATED_OPERATOR,
                    body=body,
                )
                due.append((command, key))
        # Sent outside the lock: an acknowledgement may come back on another thread at once.
        for command, key in due:
            self._dispatch(command, key)
        return [command for command, _ in due]

    def _forget_gone(self, vehicle_id: str, shown: set[_RequestKey]) -> None:
        """Drop what is remembered of the vehicle's requests that it no longer shows pending
        (answered or withdrawn), so that long runs do not accumulate them."""
        for key in [key for key in self._seen_s if key[0] == vehicle_id and key not in shown]:
            del self._seen_s[key]
        self._sent = {key for key in self._sent if key[0] != vehicle_id or key in shown}

    def _dispatch(self, command: m.Command, key: _RequestKey) -> None:
        try:
            self._send(command, lambda ack: self._finish(command, key, ack))
        except ProtocolError as exc:
            _log.warning("simulated operator: %s not sent: %s", command.vehicle_id, exc)
            self._finish(command, key, None)

    def _finish(self, command: m.Command, key: _RequestKey, ack: m.CommandAck | None) -> None:
        vehicle = command.vehicle_id
        with self._lock:
            self._outstanding[vehicle] = max(0, self._outstanding.get(vehicle, 0) - 1)
            if ack is None or not ack.accepted:
                # Seen afresh at a later step: tried again after another reaction delay.
                self._sent.discard(key)
                self._seen_s.pop(key, None)
            self._answers.append(OperatorAnswer(command, ack))
        if self._on_answer is not None:
            self._on_answer(OperatorAnswer(command, ack))

    def outstanding(self, vehicle_id: str | None = None) -> int:
        """Confirmations sent and not acknowledged yet (of one vehicle, or all)."""
        with self._lock:
            if vehicle_id is not None:
                return self._outstanding.get(vehicle_id, 0)
            return sum(self._outstanding.values())

    def take_answers(self) -> list[OperatorAnswer]:
        """The answers collected since the last call, oldest first."""
        with self._lock:
            answers, self._answers = self._answers, []
        return answers


class SimulatedOperatorThread:
    """Steps ``operator`` on the latest status of each of its vehicles every ``period_s``."""

    def __init__(
        self,
        operator: SimulatedOperator,
        latest_status: Callable[[str], m.StatusReport | None],
        *,
        period_s: float = 0.1,
        start: bool = True,
    ) -> None:
        self.operator = operator
        self._latest = latest_status
        self._period_s = period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="simulated-operator", daemon=True)
        if start:
            self._thread.start()
        # Without the thread, whoever embeds the service steps ``operator`` itself (the
        # lockstep scenario runner, between slices of simulated time).

    def _run(self) -> None:
        while not self._stop.wait(self._period_s):
            started = time.monotonic()
            for vehicle in sorted(self.operator.vehicles):
                status = self._latest(vehicle)
                if status is not None:
                    try:
                        self.operator.step(status)
                    except Exception:  # one bad step must not end the operator
                        _log.exception("simulated operator step for %s failed", vehicle)
            _log.debug("simulated operator stepped in %.3f s", time.monotonic() - started)

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(5.0)
