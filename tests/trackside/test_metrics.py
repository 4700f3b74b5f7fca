"""``GET /metrics`` (issue 23): Prometheus's text format, the fleet and the REST latency in it,
and scraping only with the token (or from the loopback interface when none is set)."""

from __future__ import annotations

import zenoh
from fastapi.testclient import TestClient
from prometheus_client.parser import text_string_to_metric_families

from protocol import ZenohSettings, open_session
from tests.conftest import wait_for
from tests.trackside.conftest import MakeClient, login, running_service

TOKEN = "scrape-token-for-the-tests"


def _scrape(client: TestClient) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    response = client.get("/metrics", headers={"Authorization": f"Bearer {TOKEN}"})
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/plain")
    return {
        (sample.name, tuple(sorted(sample.labels.items()))): sample.value
        for family in text_string_to_metric_families(response.text)
        for sample in family.samples
    }


def test_the_fleet_sessions_and_bad_payloads_are_scraped(
    router_endpoint: str, database_url: str
) -> None:
    with (
        running_service(router_endpoint, database_url, metrics_token=TOKEN) as client,
        open_session(ZenohSettings(connect=(router_endpoint,))) as peer,
    ):
        tokens: list[zenoh.LivelinessToken] = [
            peer.liveliness().declare_token("ato/alive/ob/URV7"),
            peer.liveliness().declare_token("ato/alive/ob/URV8"),
        ]
        peer.put("ato/ob/URV7/status", b"\xff not a status report")

        def scraped() -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
            return _scrape(client)

        assert wait_for(lambda: scraped().get(("ato_ts_vehicles_alive", ())) == 2.0, 10.0)
        samples = scraped()
        for vehicle in ("URV7", "URV8"):
            assert samples[("ato_ts_vehicle_alive", (("vehicle", vehicle),))] == 1.0
        assert samples[("ato_ts_sessions_open", ())] == 0.0
        assert wait_for(
            lambda: (
                scraped().get(
                    (
                        "ato_ts_messages_dropped_total",
                        (("reason", "bad_payload"), ("topic", "status")),
                    )
                )
                == 1.0
            ),
            10.0,
        ), [key for key in scraped() if key[0].startswith("ato_ts_messages")]
        tokens[1].undeclare()
        assert wait_for(lambda: scraped().get(("ato_ts_vehicles_alive", ())) == 1.0, 10.0)
        tokens[0].undeclare()


def test_rest_latency_is_a_histogram_by_route_template(make_client: MakeClient) -> None:
    client = make_client(metrics_token=TOKEN)
    headers = login(client, "root", "admin-password")
    for vehicle in ("URV1", "URV2", "URV3"):
        client.get(f"/api/v1/vehicles/{vehicle}", headers=headers)
    samples = _scrape(client)
    by_route = {
        labels: value
        for (name, labels), value in samples.items()
        if name == "ato_ts_rest_request_seconds_count"
    }
    counted = {dict(labels)["route"]: value for labels, value in by_route.items()}
    assert counted.get("/api/v1/vehicles/{vehicle_id}") == 3.0, counted
    assert not any("URV1" in route for route in counted)
    assert counted["/api/v1/auth/token"] == 1.0
    bucket = (
        "ato_ts_rest_request_seconds_bucket",
        tuple(
            sorted(
                {
                    "le": "+Inf",
                    "method": "POST",
                    "route": "/api/v1/auth/token",
                    "status": "2xx",
                }.items()
            )
        ),
    )
    assert samples[bucket] == 1.0


def test_a_scrape_needs_the_token_and_without_one_the_loopback(make_client: MakeClient) -> None:
    client = make_client(metrics_token=TOKEN)
    assert client.get("/metrics").status_code == 403
    assert client.get("/metrics", headers={"Authorization": "Bearer wrong"}).status_code == 403
    assert client.get("/metrics", headers={"Authorization": f"Basic {TOKEN}"}).status_code == 403
    assert client.get("/metrics", headers={"Authorization": f"Bearer {TOKEN}"}).status_code == 200
    # No token set: the test client's address is not the loopback's.
    assert make_client().get("/metrics").status_code == 403
