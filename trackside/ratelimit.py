"""Login rate limiting: too many failed logins for a user, or from an address, within a window
refuse further attempts (429) until the window has moved past them."""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

__all__ = ["LoginLimiter"]


class LoginLimiter:
    """Counts failed logins per username and per client address, in memory."""

    def __init__(
        self, *, max_failures: int, window_s: float, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.max_failures = max_failures
        self.window_s = window_s
        self._clock = clock
        self._lock = threading.Lock()
        self._failures: dict[tuple[str, str], deque[float]] = {}

    def _keys(self, username: str, address: str) -> tuple[tuple[str, str], tuple[str, str]]:
        return ("user", username), ("address", address)

    def _recent(self, key: tuple[str, str], now: float) -> int:
        failures = self._failures.get(key)
        if failures is None:
            return 0
        while failures and now - failures[0] >= self.window_s:
            failures.popleft()
        if not failures:
            del self._failures[key]
            return 0
        return len(failures)

    def retry_after_s(self, username: str, address: str) -> float | None:
        """None when a login may be tried; else how long until the oldest failure expires."""
        now = self._clock()
        with self._lock:
            waits = [
                self._failures[key][0] + self.window_s - now
                for key in self._keys(username, address)
                if self._recent(key, now) >= self.max_failures
            ]
        return max(waits) if waits else None

    def failed(self, username: str, address: str) -> None:
        now = self._clock()
        with self._lock:
            for key in self._keys(username, address):
                self._recent(key, now)
                self._failures.setdefault(key, deque()).append(now)

    def succeeded(self, username: str) -> None:
        """A good password clears the user's failures (not the address's)."""
        with self._lock:
            self._failures.pop(("user", username), None)
