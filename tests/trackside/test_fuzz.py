"""schemathesis over the service's own OpenAPI schema: no generated request gets a 5xx.

The service runs for real (uvicorn on loopback, its Zenoh session on a router, SQLite); every
operation of ``/openapi.json`` gets generated requests, with an admin's token so that most get
past authentication.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
import requests
import uvicorn
from hypothesis import HealthCheck, given, settings

from deploy.ports import free_tcp_port
from tests.conftest import wait_for
from tests.trackside.conftest import ADMIN
from trackside.config import Settings
from trackside.main import create_app

pytestmark = pytest.mark.slow

schemathesis = pytest.importorskip("schemathesis")

EXAMPLES_PER_OPERATION = 25


@pytest.fixture
def base_url(router_endpoint: str, tmp_path: Path) -> Iterator[str]:
    port = free_tcp_port()
    service = Settings(
        database_url=f"sqlite:///{tmp_path / 'ts.db'}",
        zenoh_connect=(router_endpoint,),
        admin_user=ADMIN[0],
        admin_password=ADMIN[1],
        login_max_failures=1000,
    )
    server = uvicorn.Server(
        uvicorn.Config(create_app(service), host="127.0.0.1", port=port, log_level="warning")
    )
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    assert wait_for(lambda: server.started, 10.0)
    yield f"http://127.0.0.1:{port}"
    server.should_exit = True
    thread.join(10.0)


def _token(http: requests.Session, base_url: str) -> dict[str, str]:
    form = dict(zip(("username", "password"), ADMIN, strict=True))
    response = http.post(f"{base_url}/api/v1/auth/token", data=form, timeout=10)
    return {"Authorization": f"Bearer {response.json()['access_token']}"}


def test_no_generated_request_gets_a_server_error(base_url: str) -> None:
    with requests.Session() as http:
        document = http.get(f"{base_url}/openapi.json", timeout=10).json()
        schema = schemathesis.openapi.from_dict(document)
        auth = _token(http, base_url)
        server_errors: list[str] = []
        statuses: dict[int, int] = {}
        operations = [result.ok() for result in schema.get_all_operations()]
        assert len(operations) >= 30

        for operation in operations:

            @settings(
                max_examples=EXAMPLES_PER_OPERATION,
                deadline=None,
                database=None,
                derandomize=True,
                suppress_health_check=list(HealthCheck),
            )
            @given(case=operation.as_strategy())
            def check(case: object) -> None:
                response = case.call(base_url=base_url, session=http, headers=auth)  # type: ignore[attr-defined]
                statuses[response.status_code] = statuses.get(response.status_code, 0) + 1
                if response.status_code >= 500:
                    server_errors.append(
                        f"{case.method} {case.formatted_path}: {response.status_code}"  # type: ignore[attr-defined]
                        f" {response.text[:200]}"
                    )
                if case.formatted_path.endswith("/auth/logout") and response.status_code == 204:  # type: ignore[attr-defined]
                    auth.update(_token(http, base_url))

            check()
        assert server_errors == []
        assert sum(statuses.values()) >= 5 * len(operations)
        assert statuses.get(200, 0) > 0
        assert statuses.get(422, 0) > 0
