"""The web console in Debian's chromium, driven by Playwright, against the real stack."""

from __future__ import annotations

import re
import shutil
import threading
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path

import httpx
import pytest

from deploy.ports import free_tcp_port
from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import RealTimeClock
from protocol import ZenohSettings, open_session
from tests.browser.conftest import (
    ADMIN,
    CHROMIUM,
    CHROMIUM_ARGS,
    Artefacts,
    console_settings,
    serving_trackside,
)
from tests.conftest import wait_for
from trackdb import TrackMap, load_seed_line

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian's chromium is not installed"),
]


@pytest.fixture
def simulated_operators() -> tuple[str, ...]:
    """The trackside's simulated operator answers URV1's VC (it confirms the power-up EB rearm)."""
    return ("URV1",)


@pytest.fixture
def moving_vehicle(router_endpoint: str, console_url: str) -> Iterator[None]:
    """URV1 running, driven through the ``console_url`` trackside, whose simulated operator
    rearms its EB."""
    with running_urv1(router_endpoint, console_url):
        yield


@contextmanager
def running_urv1(router_endpoint: str, trackside_url: str) -> Iterator[None]:
    """URV1 in real time at 5×, in remote driving at 30 km/h (once its EB is rearmed), as the
    operator at ``trackside_url`` commands it (only a trackside's sealed commands are taken)."""
    with open_session(ZenohSettings(connect=(router_endpoint,))) as session:
        node = OnboardNode(
            OnboardSettings(vehicle_id="URV1"),
            session=session,
            clock=RealTimeClock(5.0),
            track_map=TrackMap(load_seed_line("bologna-ring")),
        )
        runner = threading.Thread(target=node.run, daemon=True)
        runner.start()
        with httpx.Client(base_url=trackside_url, timeout=5.0) as client:
            login = client.post(
                "/api/v1/auth/token", data={"username": ADMIN[0], "password": ADMIN[1]}
            )
            login.raise_for_status()
            client.headers["Authorization"] = f"Bearer {login.json()['access_token']}"
            # Until URV1 is alive (select) and holds its session with the trackside (command).
            assert wait_for(lambda: _drives_at_30_kmh(client), 10.0)
        yield
        node.stop()
        runner.join(5.0)
        node.close()


def _drives_at_30_kmh(client: httpx.Client) -> bool:
    if client.post("/api/v1/vehicles/URV1/select").status_code != 200:
        return False
    answer = client.post("/api/v1/vehicles/URV1/rd-target-speed", json={"target_speed_kmh": 30})
    return answer.status_code == 200 and bool(answer.json()["accepted"])


@pytest.mark.usefixtures("moving_vehicle")
def test_fleet_page_lists_urv1_and_its_status_changes(console_url: str, tmp_path: Path) -> None:
    from playwright.sync_api import expect, sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
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
        expect(row.locator("td[data-field=operator]")).to_have_text("simulated")
        # ETCS: SR from the start, FS once the balise group at 150 m has given an MA.
        expect(row.locator("td").nth(6)).to_have_text(re.compile(r"^(SR|FS)$"))
        position = row.locator("td[data-field=position]")
        first = position.inner_text()
        expect(position).not_to_have_text(first, timeout=5000)
        speed = float(row.locator("td[data-field=speed]").inner_text())
        assert speed > 0.0
        page.screenshot(path=str(tmp_path / "console.png"))
        browser.close()


def test_the_console_reconnects_after_a_trackside_restart(
    router_endpoint: str, tmp_path: Path, artefacts: Artefacts
) -> None:
    """The service goes down and comes back on the same port and database while URV1 runs:
    the open page says so, reconnects by itself with the same login, and updates again."""
    from playwright.sync_api import expect, sync_playwright

    port = free_tcp_port()
    settings = console_settings(router_endpoint, tmp_path, ("URV1",))
    with ExitStack() as stack:
        first_service = ExitStack()
        first_service.enter_context(serving_trackside(settings, port))
        stack.callback(first_service.close)
        stack.enter_context(running_urv1(router_endpoint, f"http://127.0.0.1:{port}/"))
        playwright = stack.enter_context(sync_playwright())
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        stack.callback(browser.close)
        page = browser.new_page()
        page.goto(f"http://127.0.0.1:{port}/")
        page.fill("input[name=username]", "operator")
        page.fill("input[name=password]", "console-pw")
        page.click("button[type=submit]")
        connection = page.locator("#connection")
        position = page.locator("tr[data-vehicle=URV1] td[data-field=position]")
        expect(connection).to_have_text("live", timeout=5000)
        expect(position).not_to_have_text(position.inner_text(), timeout=5000)
        artefacts.screenshot(page, "before-restart")

        first_service.close()  # the service goes; the vehicle runs on
        expect(connection).to_have_text("offline", timeout=10_000)
        artefacts.screenshot(page, "service-down")
        with serving_trackside(settings, port):
            expect(connection).to_have_text("live", timeout=15_000)
            expect(position).not_to_have_text(position.inner_text(), timeout=10_000)
            artefacts.screenshot(page, "after-restart")
