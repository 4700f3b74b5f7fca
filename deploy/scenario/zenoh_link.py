"""The onboard ↔ trackside Zenoh link of a whole-stack run, and the ``zenoh_link_loss`` fault on it.

With a ``zenoh_link_loss`` fault, ``ato run`` connects the onboard's session to the trackside's
through a :class:`~deploy.link_proxy.LinkProxy`. :class:`ZenohLinkFault` cuts and restores that
link and waits, in wall time, until both sides have seen the change by each other's liveliness
token (``ato/alive/...``). The runner calls it between two slices of simulated time, so that the
loss and the recovery fall at ticks fixed by simulated time, whatever Zenoh's lease and its
reconnection take in wall time.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import zenoh

from deploy.link_proxy import LinkMode, LinkProxy
from protocol import LivelinessWatcher
from protocol.registry import ALIVE_ONBOARD, ALIVE_TRACKSIDE

__all__ = ["SETTLE_S", "ZenohLinkFault"]

SETTLE_S = 1.5
"""How long, in wall time, a restored link must hold before the run goes on [s] (longer than the
1 s link lease)."""


class ZenohLinkFault:
    """The proxied link and a liveliness watcher on each side of it.

    :meth:`cut` and :meth:`restore` return once each side's watcher has lost (or found again) the
    other side's token.
    """

    RECONNECT = "retry_period_init_ms=100;retry_period_max_ms=500;retry_period_increase_factor=2"
    """Connect options of the proxied endpoint: retry every 0.1–0.5 s of wall time (Zenoh's
    defaults back off to 4 s), so that the link is back within a few tenths of a second."""

    def __init__(
        self,
        proxy: LinkProxy,
        *,
        onboard: zenoh.Session,
        trackside: zenoh.Session,
        vehicle_id: str,
    ) -> None:
        self.proxy = proxy
        self._trackside_seen = LivelinessWatcher(onboard, ALIVE_TRACKSIDE.format(instance="*"))
        self._onboard_seen = LivelinessWatcher(trackside, ALIVE_ONBOARD.format(vehicle=vehicle_id))
        self.connections_dropped = 0
        self.flaps = 0
        """Times a side lost the other's token again while the restored link settled."""

    @classmethod
    def connect_endpoint(cls, proxy: LinkProxy) -> str:
        """The endpoint the onboard's session connects to."""
        return f"{proxy.endpoint}#{cls.RECONNECT}"

    @property
    def up(self) -> bool:
        return self.proxy.up

    def _both_seen(self) -> bool:
        return bool(self._trackside_seen.alive()) and bool(self._onboard_seen.alive())

    def _neither_seen(self) -> bool:
        return not self._trackside_seen.alive() and not self._onboard_seen.alive()

    def cut(self, mode: LinkMode, *, timeout_s: float) -> bool:
        """Cut the link; False if a side still sees the other after ``timeout_s`` [s]."""
        self.connections_dropped += self.proxy.cut(mode)
        return _wait_for(self._neither_seen, timeout_s)

    def restore(self, *, timeout_s: float) -> bool:
        """Restore the link; False if the sessions have not met again after ``timeout_s`` [s].

        The sessions must then keep seeing each other for :data:`SETTLE_S`: connections made or
        held while the link was cut are dropped around the restore, and a token lost again a
        moment after it came back would otherwise fall on the new session at a tick set by
        wall time."""
        self.proxy.restore()
        deadline = time.monotonic() + timeout_s
        while _wait_for(self._both_seen, deadline - time.monotonic()):
            settled = time.monotonic() + SETTLE_S
            while self._both_seen() and time.monotonic() < settled:
                time.sleep(0.01)
            if self._both_seen():
                return True
            self.flaps += 1
        return False

    def close(self) -> None:
        self._trackside_seen.close()
        self._onboard_seen.close()


def _wait_for(condition: Callable[[], bool], timeout_s: float) -> bool:
    """Poll ``condition`` in wall time until it holds or ``timeout_s`` [s] has passed."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return condition()
        time.sleep(0.001)
    return True
