"""Browser-test fixtures: a live trackside on loopback, Debian's chromium, screenshot artefacts."""

from __future__ import annotations

import os
import shutil
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import uvicorn

from deploy.ports import free_tcp_port
from tests.conftest import wait_for
from trackside.config import Settings
from trackside.main import create_app

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
ADMIN = ("operator", "console-pw")
"""The admin the trackside creates at start-up; the tests log in as this person."""


@pytest.fixture
def simulated_operators() -> tuple[str, ...]:
    """Vehicles whose VC requests the trackside's simulated operator answers: none, so that only
    the person at the console answers; a test module overrides this fixture to configure one."""
    return ()


@pytest.fixture
def console_url(
    router_endpoint: str, tmp_path: Path, simulated_operators: tuple[str, ...]
) -> Iterator[str]:
    """A trackside service (uvicorn in a thread, SQLite file) joined to the test's router."""
    port = free_tcp_port()
    with serving_trackside(console_settings(router_endpoint, tmp_path, simulated_operators), port):
        yield f"http://127.0.0.1:{port}/"


def console_settings(
    router_endpoint: str, directory: Path, simulated_operators: tuple[str, ...] = ()
) -> Settings:
    """The console tests' trackside: a SQLite file in ``directory``, the test's router."""
    return Settings(
        database_url=f"sqlite:///{directory / 'ts.db'}",
        zenoh_connect=(router_endpoint,),
        admin_user=ADMIN[0],
        admin_password=ADMIN[1],
        simulated_operators=simulated_operators,
    )


@contextmanager
def serving_trackside(settings: Settings, port: int) -> Iterator[None]:
    """The trackside app under uvicorn in a thread on ``port``, until the block ends."""
    server = uvicorn.Server(
        uvicorn.Config(create_app(settings), host="127.0.0.1", port=port, log_level="warning")
    )
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    assert wait_for(lambda: server.started, 10.0)
    try:
        yield
    finally:
        server.should_exit = True
        thread.join(10.0)


@pytest.fixture
def chromium() -> Iterator[Any]:
    """Debian's chromium, headless, through Playwright."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield browser
        browser.close()


class Artefacts:
    """Screenshots under the test's tmp_path, copied to ``ATO_ARTEFACTS_DIR`` when it is set."""

    def __init__(self, directory: Path, test_name: str) -> None:
        self.directory = directory
        self.test_name = test_name
        self.paths: list[Path] = []

    def screenshot(self, page: Any, name: str) -> Path:
        path = self.directory / f"{len(self.paths):02d}-{name}.png"
        page.screenshot(path=str(path), full_page=True)
        self.paths.append(path)
        return path

    def publish(self) -> None:
        target = os.environ.get("ATO_ARTEFACTS_DIR")
        if not target:
            return
        destination = Path(target) / self.test_name
        destination.mkdir(parents=True, exist_ok=True)
        for path in self.paths:
            shutil.copy2(path, destination / path.name)


@pytest.fixture
def artefacts(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[Artefacts]:
    shots = tmp_path / "screenshots"
    shots.mkdir()
    collected = Artefacts(shots, request.node.name)
    yield collected
    collected.publish()
