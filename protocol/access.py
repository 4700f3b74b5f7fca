"""The routers' access control: who may say what on the key space, from the registry.

A router of a deployment runs Zenoh's access control with ``default_permission = "deny"``,
keyed on the common name of each peer's TLS certificate (``ato pki``, docs/security.md):

- a trackside instance and another router may do anything under ``ato/**``;
- vehicle X may publish only the onboard's topics under its own id (``ato/ob/X/...``), query
  only the trackside's services for X (its session, its current MA, the line versions), answer
  only the commands addressed to X, subscribe only to what is addressed to X, and declare only
  its own liveliness token ``ato/alive/ob/X`` (and watch the tracksides');
- anyone else, and anything else, is refused.

Each rule is derived from :data:`protocol.registry.TOPICS` by the topic's direction, so that a
topic added to the registry is covered by the same policy. Zenoh's ACL is fixed when the
router starts: the vehicles are listed then, and adding one means restarting the router with
the new list (its sessions reconnect on their own).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from protocol.registry import (
    ALIVE_ONBOARD,
    ALIVE_TRACKSIDE,
    TOPICS,
    Delivery,
    Direction,
    RegistryTopic,
)

__all__ = ["ALL_MESSAGES", "access_control"]

ALL_MESSAGES = (
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "declare_queryable",
    "reply",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
)
"""Every message kind Zenoh's access control filters."""


def _key(topic: RegistryTopic, vehicle: str) -> str:
    """The topic's key for ``vehicle``, its other chunks (a line's id) any."""
    chunks = {name: ("*" if name != "vehicle" else vehicle) for name in topic.chunk_names}
    return topic.key_template.format(**chunks)


def _rule(rule_id: str, messages: Iterable[str], flow: str, keys: Sequence[str]) -> dict[str, Any]:
    return {
        "id": rule_id,
        "permission": "allow",
        "flows": [flow],
        "messages": list(messages),
        "key_exprs": list(keys),
    }


def _vehicle_rules(vehicle: str) -> list[dict[str, Any]]:
    """What vehicle ``vehicle`` may send (ingress) and be sent (egress)."""
    ours = [t for t in TOPICS if "vehicle" in t.chunk_names]
    query = [t for t in ours if t.delivery is Delivery.QUERY]
    plain = [t for t in ours if t.delivery is not Delivery.QUERY]
    sends = [_key(t, vehicle) for t in plain if t.direction is not Direction.TRACKSIDE_TO_ONBOARD]
    hears = [_key(t, vehicle) for t in plain if t.direction is not Direction.ONBOARD_TO_TRACKSIDE]
    answers = [_key(t, vehicle) for t in query if t.direction is Direction.TRACKSIDE_TO_ONBOARD]
    asks = [_key(t, vehicle) for t in query if t.direction is Direction.ONBOARD_TO_TRACKSIDE]
    # Services for every vehicle keyed by another chunk only (a line's version).
    asks += [
        _key(t, vehicle)
        for t in TOPICS
        if t.delivery is Delivery.QUERY
        and "vehicle" not in t.chunk_names
        and t.direction is Direction.ONBOARD_TO_TRACKSIDE
    ]
    # The trackside's declarations towards the vehicle: its subscribers and queryables serve
    # every vehicle (``ato/ob/*/status``), and a publisher drops what no declared subscriber it
    # knows of matches. A declaration carries no data.
    sent_to = [t.wildcard() for t in plain if t.direction is not Direction.TRACKSIDE_TO_ONBOARD]
    asked_of = [t.wildcard() for t in query if t.direction is Direction.ONBOARD_TO_TRACKSIDE]
    asked_of += [k for k in asks if "*" in k]
    token, tracksides = ALIVE_ONBOARD.format(vehicle=vehicle), ALIVE_TRACKSIDE.format(instance="*")
    prefix = f"{vehicle}:"
    return [
        _rule(prefix + "sends", ["put", "delete"], "ingress", sends),
        _rule(prefix + "sends-to", ["declare_subscriber"], "egress", sent_to),
        _rule(prefix + "hears", ["declare_subscriber"], "ingress", hears),
        _rule(prefix + "hears-from", ["put", "delete"], "egress", hears),
        _rule(prefix + "answers", ["declare_queryable", "reply"], "ingress", answers),
        _rule(prefix + "answers-to", ["query"], "egress", answers),
        _rule(prefix + "asks", ["query"], "ingress", asks),
        _rule(prefix + "asks-of", ["declare_queryable"], "egress", asked_of),
        _rule(prefix + "answered", ["reply"], "egress", asks),
        _rule(prefix + "alive", ["liveliness_token"], "ingress", [token]),
        _rule(
            prefix + "watches",
            ["declare_liveliness_subscriber", "liveliness_query"],
            "ingress",
            [tracksides],
        ),
        _rule(prefix + "watches-from", ["liveliness_token", "reply"], "egress", [tracksides]),
    ]


def access_control(
    *, vehicles: Sequence[str], tracksides: Sequence[str], routers: Sequence[str] = ()
) -> dict[str, Any]:
    """The ``access_control`` section of a router's configuration for a deployment.

    Parameters
    ----------
    vehicles
        The vehicles' ids, the common names of their certificates.
    tracksides
        The trackside instances' certificate names.
    routers
        The other routers' certificate names (multi-machine set-ups).
    """
    rules = [
        _rule("trusted-in", ALL_MESSAGES, "ingress", ["ato/**"]),
        _rule("trusted-out", ALL_MESSAGES, "egress", ["ato/**"]),
    ]
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    trusted = [*tracksides, *routers]
    if trusted:
        subjects.append({"id": "trusted", "cert_common_names": list(trusted)})
        policies.append({"rules": ["trusted-in", "trusted-out"], "subjects": ["trusted"]})
    for vehicle in vehicles:
        own = _vehicle_rules(vehicle)
        rules += own
        subjects.append({"id": f"vehicle:{vehicle}", "cert_common_names": [vehicle]})
        policies.append({"rules": [r["id"] for r in own], "subjects": [f"vehicle:{vehicle}"]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }
