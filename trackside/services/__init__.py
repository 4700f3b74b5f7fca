"""Trackside services: domain rules over persistence, raising :mod:`trackside.errors`."""

__all__ = []
