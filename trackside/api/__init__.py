"""HTTP and WebSocket layer: the only place that knows about status codes."""

__all__ = []
