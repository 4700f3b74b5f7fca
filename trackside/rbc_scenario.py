"""RBC scenario scripts: timed movement-authority actions run against an :class:`RbcEmulator`.

A script lists actions, each at a time from the scenario's start [s] for one vehicle::

    name: first-lap
    actions:
      - {at_s: 0, vehicle: URV1, action: issue, line_id: bologna-ring,
         start_m: 0, end_of_authority_m: 800}
      - {at_s: 60, vehicle: URV1, action: extend, end_of_authority_m: 1500, overlap_m: 50}
      - {at_s: 90, vehicle: URV1, action: shorten, end_of_authority_m: 1200}
      - {at_s: 120, vehicle: URV1, action: revoke}

An ``issue`` takes the fields of :class:`~trackside.rbc.MovementAuthorityIssue`; ``extend`` and
``shorten`` those of :class:`protocol.messages.MovementAuthorityEnd`; ``revoke`` none. Files are
YAML (``.yaml``, ``.yml``), JSON (``.json``) or TOML (``.toml``, an ``[[actions]]`` array).
:func:`load_scenario` reports every problem of a file at once, each with its place
(``actions[1].end_of_authority_m: Field required``), as a
:class:`~trackside.errors.RbcScenarioError`.

:class:`RbcScenarioRunner` runs the actions that are due at the time of the clock it is given, in
time order (the file's order for equal times). Driven by a simulated clock it is deterministic:
the same script gives the same messages at the same simulated times. An action the RBC refuses
is logged and recorded in :attr:`RbcScenarioRunner.outcomes`; the script goes on.
"""

from __future__ import annotations

import json
import logging
import threading
import tomllib
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator
from pydantic_core import ErrorDetails

from protocol import ProtocolError
from protocol import messages as m
from trackside.errors import RbcScenarioError, TracksideError
from trackside.rbc import Clock, MovementAuthorityIssue, RbcEmulator

__all__ = [
    "ActionOutcome",
    "ExtendAction",
    "IssueAction",
    "RbcAction",
    "RbcScenario",
    "RbcScenarioRunner",
    "RbcScenarioThread",
    "RevokeAction",
    "ShortenAction",
    "ScenarioFormat",
    "apply_action",
    "load_scenario",
    "parse_scenario",
]

ScenarioFormat = Literal["yaml", "json", "toml"]
_SUFFIXES: dict[str, ScenarioFormat] = {
    ".yaml": "yaml",
    ".yml": "yaml",
    ".json": "json",
    ".toml": "toml",
}
_ACTIONS = ("issue", "extend", "shorten", "revoke")
TIME_TOLERANCE_S = 1e-9
"""An action is due when the clock is within this of its time [s]: sums of floats round."""

_log = logging.getLogger(__name__)


class _Timed(BaseModel):
    """When and for whom an action runs."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    at_s: float = Field(ge=0.0, allow_inf_nan=False, description="From the start [s]")
    vehicle: str = Field(pattern=r"^[A-Za-z0-9_-]{1,32}$", description="Vehicle id")


class IssueAction(_Timed, MovementAuthorityIssue):
    """Issue a new MA (replacing any the vehicle holds)."""

    action: Literal["issue"]


class ExtendAction(_Timed, m.MovementAuthorityEnd):
    """Move the EoA forward, with the new end's danger point, overlap and release speed."""

    action: Literal["extend"]


class ShortenAction(_Timed, m.MovementAuthorityEnd):
    """Move the EoA back; refused if it would fall at or behind the vehicle."""

    action: Literal["shorten"]


class RevokeAction(_Timed):
    """Withdraw the vehicle's MA."""

    action: Literal["revoke"]


RbcAction = Annotated[
    IssueAction | ExtendAction | ShortenAction | RevokeAction, Field(discriminator="action")
]


class RbcScenario(BaseModel):
    """A validated RBC scenario script."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str | None = Field(default=None, max_length=128)
    description: str | None = Field(default=None, max_length=4096)
    actions: tuple[RbcAction, ...] = Field(max_length=10_000)

    @field_validator("actions")
    @classmethod
    def _some_actions(cls, actions: tuple[RbcAction, ...]) -> tuple[RbcAction, ...]:
        # Not min_length: that one also fires, confusingly, when every action is invalid.
        if not actions:
            raise ValueError("a scenario needs at least one action")
        return actions

    def ordered(self) -> list[tuple[int, RbcAction]]:
        """``(index in the file, action)`` in time order, the file's order for equal times."""
        return sorted(enumerate(self.actions), key=lambda pair: (pair[1].at_s, pair[0]))


def apply_action(rbc: RbcEmulator, action: RbcAction) -> m.MovementAuthorityMessage:
    """Run one action on the RBC; its refusals raise as the RBC's methods do."""
    if isinstance(action, IssueAction):
        return rbc.issue(action.vehicle, action)
    if isinstance(action, ExtendAction):
        return rbc.extend(action.vehicle, action)
    if isinstance(action, ShortenAction):
        return rbc.shorten(action.vehicle, action)
    return rbc.revoke(action.vehicle)


@dataclass(frozen=True, kw_only=True)
class ActionOutcome:
    """What one action did: the MA message sent, or why it was refused."""

    index: int
    """The action's place in the file, from 0."""
    action: RbcAction
    time_s: float
    """The clock's time when it ran [s]."""
    message: m.MovementAuthorityMessage | None
    error: str | None


class RbcScenarioRunner:
    """Runs a scenario's due actions on each :meth:`step`, against the clock given.

    Parameters
    ----------
    scenario
        The script.
    rbc
        The emulator the actions go to.
    clock
        The time [s]; the RBC's clock by default.
    start_s
        The scenario's start on that clock [s]; the clock's time now by default.
    """

    def __init__(
        self,
        scenario: RbcScenario,
        rbc: RbcEmulator,
        *,
        clock: Clock | None = None,
        start_s: float | None = None,
    ) -> None:
        self.scenario = scenario
        self._rbc = rbc
        self._clock = rbc.clock if clock is None else clock
        self.start_s = self._clock() if start_s is None else start_s
        self._pending = deque(scenario.ordered())
        self.outcomes: list[ActionOutcome] = []

    @property
    def done(self) -> bool:
        """Every action has run."""
        return not self._pending

    @property
    def next_due_s(self) -> float | None:
        """Clock time [s] of the next action; ``None`` when done."""
        return self.start_s + self._pending[0][1].at_s if self._pending else None

    def step(self) -> list[ActionOutcome]:
        """Run every action due by the clock's time now, in order; their outcomes."""
        now_s = self._clock()
        ran: list[ActionOutcome] = []
        while self._pending and self.start_s + self._pending[0][1].at_s <= now_s + TIME_TOLERANCE_S:
            index, action = self._pending.popleft()
            try:
                message, error = apply_action(self._rbc, action), None
            except (TracksideError, ProtocolError) as exc:
                message, error = None, str(exc)
                _log.warning(
                    "RBC scenario action %d (%s %s at %g s) refused: %s",
                    index,
                    action.action,
                    action.vehicle,
                    action.at_s,
                    exc,
                )
            ran.append(
                ActionOutcome(
                    index=index, action=action, time_s=now_s, message=message, error=error
                )
            )
        self.outcomes.extend(ran)
        return ran

    def run(self, stop: threading.Event, *, period_s: float = 0.05) -> None:
        """Step every ``period_s`` [s] of wall time until done or ``stop`` is set."""
        while not self.done and not stop.is_set():
            self.step()
            stop.wait(period_s)


class RbcScenarioThread:
    """Runs a scenario in a daemon thread against its clock, for the live service."""

    def __init__(self, runner: RbcScenarioRunner, *, period_s: float = 0.05) -> None:
        self.runner = runner
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=runner.run,
            args=(self._stop,),
            kwargs={"period_s": period_s},
            name="rbc-scenario",
            daemon=True,
        )
        self._thread.start()

    def close(self, timeout_s: float = 5.0) -> None:
        self._stop.set()
        self._thread.join(timeout_s)


def load_scenario(path: str | Path) -> RbcScenario:
    """Read and validate a scenario file; its format from the suffix."""
    path = Path(path)
    scenario_format = _SUFFIXES.get(path.suffix.lower())
    if scenario_format is None:
        raise RbcScenarioError(
            f"{path}: unknown RBC scenario format {path.suffix!r}; use " + ", ".join(_SUFFIXES)
        )
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RbcScenarioError(f"cannot read RBC scenario {path}: {exc}") from exc
    return parse_scenario(text, scenario_format, source=str(path))


def parse_scenario(
    text: str, scenario_format: ScenarioFormat = "yaml", *, source: str = "<scenario>"
) -> RbcScenario:
    """Validate a scenario given as text."""
    document = _decode(text, scenario_format, source)
    try:
        return RbcScenario.model_validate(document)
    except ValidationError as exc:
        problems = [_problem(error) for error in exc.errors()]
        listing = "\n  ".join(problems)
        raise RbcScenarioError(
            f"{source}: {len(problems)} problem(s) in the RBC scenario:\n  {listing}", problems
        ) from exc


def _decode(text: str, scenario_format: ScenarioFormat, source: str) -> Any:
    try:
        if scenario_format == "json":
            return json.loads(text)
        if scenario_format == "toml":
            return tomllib.loads(text)
        return yaml.safe_load(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError, yaml.YAMLError) as exc:
        raise RbcScenarioError(f"{source}: not valid {scenario_format.upper()}: {exc}") from exc


def _problem(error: ErrorDetails) -> str:
    """One validation error as ``actions[1].end_of_authority_m: message (got ...)``."""
    place = ""
    location = error["loc"]
    for position, part in enumerate(location):
        if isinstance(part, int):
            place += f"[{part}]"
        elif position > 0 and isinstance(location[position - 1], int) and part in _ACTIONS:
            continue  # the union's tag: the action's own name, already in the file
        else:
            place += f".{part}" if place else str(part)
    message = str(error["msg"]).removeprefix("Value error, ")
    given = error.get("input")
    if error["type"] != "missing" and isinstance(given, str | int | float | bool | None):
        message += f" (got {given!r})"
    return f"{place or 'scenario'}: {message}"
