"""Journey profiles to a vehicle over Zenoh: the profile goes out on
``ato/ob/{vehicle}/journey``, sealed for the vehicle's session, and the sender waits for the
onboard's acknowledgement (or rejection) of that journey and version on
``ato/ts/{vehicle}/journey_ack``. Acknowledgements under another vehicle's key are dropped.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh

from protocol import TopicStats, TypedPublisher, TypedSubscriber
from protocol import messages as m
from protocol.registry import JOURNEY_PROFILE, JOURNEY_PROFILE_ACK, Topic

__all__ = ["JourneyProfileLink"]

PublisherLookup = Callable[[Topic[Any], str], TypedPublisher[Any]]
"""The publisher of a topic for a vehicle (one per topic and vehicle, declared at first use)."""
Sealer = Callable[[str], m.Freshness | None]
"""The session id and next number for a message to a vehicle (``None``: no session)."""


class JourneyProfileLink:
    """Sends journey profiles and collects the onboards' acknowledgements."""

    def __init__(self, session: zenoh.Session, *, publisher: PublisherLookup, seal: Sealer) -> None:
        self._publisher = publisher
        self._seal = seal
        self._acks: dict[str, list[m.JourneyProfileAck]] = {}
        self._acks_changed = threading.Condition()
        self._subscriber = TypedSubscriber(
            session, JOURNEY_PROFILE_ACK, on_message=self._on_ack, vehicle="*"
        )

    @property
    def stats(self) -> TopicStats:
        return self._subscriber.stats

    @property
    def topic_name(self) -> str:
        return self._subscriber.topic.name

    def _on_ack(self, key: str, ack: m.JourneyProfileAck) -> None:
        if ack.vehicle_id != JOURNEY_PROFILE_ACK.parse(key)["vehicle"]:
            return
        with self._acks_changed:
            self._acks.setdefault(ack.vehicle_id, []).append(ack)
            self._acks_changed.notify_all()

    def send(self, profile: m.JourneyProfile, *, timeout_s: float) -> m.JourneyProfileAck | None:
        """Send a journey profile and wait for its acknowledgement (or rejection); ``None``
        when none came within ``timeout_s`` of wall time."""
        vehicle = profile.vehicle_id
        profile = profile.model_copy(update={"freshness": self._seal(vehicle)})
        with self._acks_changed:
            self._acks.pop(vehicle, None)
        self._publisher(JOURNEY_PROFILE, vehicle).put(profile)
        deadline = time.monotonic() + timeout_s

        def answered() -> m.JourneyProfileAck | None:
            for ack in self._acks.get(vehicle, []):
                if (ack.journey_id, ack.version) == (profile.journey_id, profile.version):
                    return ack
            return None

        with self._acks_changed:
            while (ack := answered()) is None:
                left = deadline - time.monotonic()
                if left <= 0 or not self._acks_changed.wait(left):
                    return answered()
            return ack

    def close(self) -> None:
        self._subscriber.close()
