"""A liveliness token whose key is not a vehicle's is dropped and counted (issue 20): one bad
token must not break the fleet view."""

from __future__ import annotations

import zenoh

from protocol import ZenohSettings, open_session
from tests.conftest import wait_for
from tests.trackside.conftest import login, running_service


def test_a_bad_vehicle_id_in_a_liveliness_token_does_not_break_the_fleet_view(
    router_endpoint: str, database_url: str
) -> None:
    with (
        running_service(router_endpoint, database_url) as client,
        open_session(ZenohSettings(connect=(router_endpoint,))) as peer,
    ):
        tokens: list[zenoh.LivelinessToken] = [
            peer.liveliness().declare_token("ato/alive/ob/Bad.Id"),
            peer.liveliness().declare_token("ato/alive/ob/" + "X" * 40),
            peer.liveliness().declare_token("ato/alive/ob/URV7"),
        ]
        headers = login(client, "root", "admin-password")
        bridge = client.app.state.bridge  # type: ignore[attr-defined]
        assert wait_for(lambda: bridge.bad_liveliness == 2, 10.0)

        def fleet() -> object:
            response = client.get("/api/v1/vehicles", headers=headers)
            assert response.status_code == 200, response.text
            return [(v["id"], v["alive"]) for v in response.json()]

        assert wait_for(lambda: fleet() == [("URV7", True)], 10.0), fleet()
        for token in tokens:
            token.undeclare()
