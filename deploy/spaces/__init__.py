"""Generator spaces: what ``ato campaign --generate`` draws scenarios from (docs/scenarios.md)."""

__all__ = []
