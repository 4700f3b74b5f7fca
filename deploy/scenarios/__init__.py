"""The scenario library: one TOML file per scenario (``ato scenarios`` lists them)."""

__all__ = []
