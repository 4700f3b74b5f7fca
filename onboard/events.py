"""What the onboard's parts note for the trackside's event log, before the node publishes it."""

from __future__ import annotations

from dataclasses import dataclass

from protocol import messages as m

__all__ = ["StackEvent"]


@dataclass(frozen=True)
class StackEvent:
    """One event: its severity, its dotted code (``journey.stop_overrun``) and its text."""

    severity: m.EventSeverity
    code: str
    text: str
