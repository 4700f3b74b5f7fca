"""Zenoh configurations: no scouting, explicit endpoints, short lease."""

from __future__ import annotations

import json

import pytest

from protocol import TransportError, ZenohSettings, open_session, zenoh_config


@pytest.mark.parametrize("mode", ["peer", "client", "router"])
def test_config_has_no_scouting_and_a_short_lease(mode: str) -> None:
    config = zenoh_config(mode=mode, connect=("tcp/127.0.0.1:7447",))  # type: ignore[arg-type]

    def read(key: str) -> object:
        return json.loads(config.get_json(key))  # get_json answers JSON text

    assert read("scouting/multicast/enabled") is False
    assert read("scouting/gossip/enabled") is False
    assert read("transport/link/tx/lease") == 1000
    assert read("connect/endpoints") == ["tcp/127.0.0.1:7447"]


@pytest.mark.parametrize(
    "kwargs",
    [
        {"mode": "peer", "lease_ms": 5000},
        {"mode": "peer", "lease_ms": 0},
        {"mode": "client"},
        {"mode": "peer", "connect": ("127.0.0.1:7447",)},
    ],
)
def test_config_refuses_unsafe_settings(kwargs: dict[str, object]) -> None:
    with pytest.raises(ValueError, match="lease|endpoint"):
        zenoh_config(**kwargs)  # type: ignore[arg-type]


def test_client_without_router_fails_with_transport_error() -> None:
    from deploy.ports import loopback_endpoint

    settings = ZenohSettings(mode="client", connect=(loopback_endpoint(),))
    with pytest.raises(TransportError), open_session(settings, connect_timeout_s=0.3):
        pass
