"""One module per resource under ``/api/v1/``."""

__all__ = []
