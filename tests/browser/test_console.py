"""The web console in Debian's chromium, driven by Playwright, against the real stack."""

from __future__ import annotations

import re
import shutil
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
import uvicorn

from deploy.ports import free_tcp_port
from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import RealTimeClock
from protocol import ZenohSettings, open_session, request
from protocol import messages as m
from protocol.registry import COMMAND
from tests.conftest import wait_for
from trackdb import TrackMap, load_seed_line
from trackside.config import Settings
from trackside.main import create_app

CHROMIUM = "/usr/bin/chromium"
pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian's chromium is not installed"),
]


@pytest.fixture
def console_url(router_endpoint: str, tmp_path: Path) -> Iterator[str]:
    port = free_tcp_port()
    settings = Settings(
        database_url=f"sqlite:///{tmp_path / 'ts.db'}", zenoh_connect=(router_endpoint,),
        admin_user="operator", admin_password="console-pw",  # type: ignore[arg-type]
    )  # fmt: skip
    server = uvicorn.Server(
        uvicorn.Config(create_app(settings), host="127.0.0.1", port=port, log_level="warning")
    )
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    assert wait_for(lambda: server.started, 10.0)
    yield f"http://127.0.0.1:{port}/"
    server.should_exit = True
    thread.join(10.0)


@pytest.fixture
def moving_vehicle(router_endpoint: str) -> Iterator[None]:
    with open_session(ZenohSettings(connect=(router_endpoint,))) as session:
        node = OnboardNode(
            OnboardSettings(vehicle_id="URV1"), session=session, clock=RealTimeClock(5.0),
            track_map=TrackMap(load_seed_line("bologna-ring")),
        )  # fmt: skip
        runner = threading.Thread(target=node.run, daemon=True)
        runner.start()
        command = m.Command(
            vehicle_id="URV1", command_id=1, issued_by="browser-test",
            body=m.RemoteDrivingTargetCommand(target_speed_mps=30 / 3.6),
        )  # fmt: skip
        assert wait_for(lambda: _accepted(session, command), 5.0)
        yield
        node.stop()
        runner.join(5.0)
        node.close()


def _accepted(session: object, command: m.Command) -> bool:
    try:
        return bool(request(session, COMMAND, command, timeout_s=0.5, vehicle="URV1").accepted)  # type: ignore[arg-type]
    except Exception:
        return False


@pytest.mark.usefixtures("moving_vehicle")
def test_fleet_page_lists_urv1_and_its_status_changes(console_url: str, tmp_path: Path) -> None:
    from playwright.sync_api import expect, sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=CHROMIUM,
            args=[
                "--no-sandbox",
                "--disable-gpu",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
            ],
        )
        page = browser.new_page()
        page.goto(console_url)
        page.fill("input[name=username]", "operator")
        page.fill("input[name=password]", "wrong")
        page.click("button[type=submit]")
        expect(page.locator("#login-error")).to_contain_text("Wrong")

        page.fill("input[name=password]", "console-pw")
        page.click("button[type=submit]")
        row = page.locator("tr[data-vehicle=URV1]")
        expect(row).to_be_visible(timeout=5000)
        expect(page.locator("#connection")).to_have_text("live")
        expect(row.locator("td").nth(1)).to_have_text("yes")
        # ETCS: SR from the start, FS once the balise group at 150 m has given an MA.
        expect(row.locator("td").nth(6)).to_have_text(re.compile(r"^(SR|FS)$"))
        position = row.locator("td[data-field=position]")
        first = position.inner_text()
        expect(position).not_to_have_text(first, timeout=5000)
        speed = float(row.locator("td[data-field=speed]").inner_text())
        assert speed > 0.0
        page.screenshot(path=str(tmp_path / "console.png"))
        browser.close()
