"""Conditions on the vehicle's state, for the triggers of a scenario's actions.

A condition is clauses joined by ``and``; a clause compares a field with a value
(``etcs_mode == FS``, ``speed_kmh < 1``) or names a boolean field (``standstill``,
``not vc_eb``). Nothing is evaluated as Python: the fields are a fixed table, the values
numbers or bare words.

=================  ======  ===============================================================
field              type    what
=================  ======  ===============================================================
time_s             number  simulated time [s]
position_m         number  the vehicle's chainage on the line (as reported) [m]
speed_kmh          number  the vehicle's speed (as reported) [km/h]
etcs_mode          word    ETCS mode: SB, SR, FS, AD, OS, TR, PT, IS, ...
ato_state          word    ATO-OB state: CO, NA, AV, RE, EG, DE, FA, ...
sc_state           word    supervisory controller: OFF, RD, AD, HRD2AD, HAD2RD
standstill         bool    the vehicle stands
vc_eb              bool    the Vital Control's EB is applied
vc_decay           bool    the Vital Control is in System Decay
journey_accepted   bool    a journey profile is accepted on board
journey_ended      bool    the end of the journey is reached
etcs_braked        bool    ETCS has commanded a service or emergency brake in this run
next_stop          word    the journey's timing point the train runs to next (``none``)
eoa_distance_m     number  ETCS's distance to its end of authority (inf without one) [m]
=================  ======  ===============================================================

``next_stop`` with ``position_m`` places an event exactly relative to the train
(``next_stop == tp2-south and position_m >= 2600``: once in the leg to that timing point, at that
chainage), which simulated time cannot: the generator of ``deploy.scenario.generate`` puts its
TSRs and MA shortenings so.
"""

from __future__ import annotations

import operator
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["FIELDS", "Clause", "Condition", "State", "parse_condition"]

State = Mapping[str, float | str | bool]
"""A snapshot of the fields above."""

FIELDS: dict[str, type] = {
    "time_s": float,
    "position_m": float,
    "speed_kmh": float,
    "etcs_mode": str,
    "ato_state": str,
    "sc_state": str,
    "standstill": bool,
    "vc_eb": bool,
    "vc_decay": bool,
    "journey_accepted": bool,
    "journey_ended": bool,
    "etcs_braked": bool,
    "next_stop": str,
    "eoa_distance_m": float,
}
_OPERATORS: dict[str, Callable[[Any, Any], bool]] = {
    "==": operator.eq,
    "!=": operator.ne,
    "<=": operator.le,
    ">=": operator.ge,
    "<": operator.lt,
    ">": operator.gt,
}
_CLAUSE = re.compile(
    r"^\s*(?:(not)\s+)?([a-z_]+)\s*(?:(==|!=|<=|>=|<|>)\s*([A-Za-z0-9_.+-]+))?\s*$"
)


@dataclass(frozen=True)
class Clause:
    field: str
    op: str
    value: float | str | bool

    def holds(self, state: State) -> bool:
        return _OPERATORS[self.op](state[self.field], self.value)


@dataclass(frozen=True)
class Condition:
    text: str
    clauses: tuple[Clause, ...]

    def holds(self, state: State) -> bool:
        return all(clause.holds(state) for clause in self.clauses)


def _clause(text: str) -> Clause:
    match = _CLAUSE.match(text)
    if match is None:
        raise ValueError(f"cannot read the clause {text.strip()!r}")
    negated, field, op, raw = match.groups()
    kind = FIELDS.get(field)
    if kind is None:
        raise ValueError(f"unknown field {field!r}; known: {', '.join(FIELDS)}")
    if op is None:
        if kind is not bool:
            raise ValueError(f"{field} is not a boolean: compare it with a value")
        return Clause(field, "==", not negated)
    if negated:
        raise ValueError(f"'not' goes with a boolean field alone, not with {op!r}")
    if kind is bool:
        if raw not in ("true", "false"):
            raise ValueError(f"{field} is true or false, not {raw!r}")
        value: float | str | bool = raw == "true"
    elif kind is float:
        try:
            value = float(raw)
        except ValueError as exc:
            raise ValueError(f"{field} compares with a number, not {raw!r}") from exc
    else:
        value = raw
    if kind is not float and op not in ("==", "!="):
        raise ValueError(f"{field} can only be compared with == or !=")
    return Clause(field, op, value)


def parse_condition(text: str) -> Condition:
    """Parse ``text``; a ``ValueError`` says what is wrong."""
    parts = re.split(r"\s+and\s+", text.strip())
    if not text.strip():
        raise ValueError("an empty condition")
    return Condition(text, tuple(_clause(part) for part in parts))
