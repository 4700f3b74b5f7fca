"""The console under the trackside's Content-Security-Policy (issue 20): every view works, no
directive is violated, and the WebSockets authenticate in their first message; a held vehicle
shows the end of its lease."""

from __future__ import annotations

import re
import shutil
import threading
from collections.abc import Iterator
from typing import Any

import pytest

from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import RealTimeClock
from protocol import ZenohSettings, open_session
from tests.browser.conftest import ADMIN, CHROMIUM, Artefacts
from trackdb import TrackMap, load_seed_line

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian's chromium is not installed"),
]

WAIT_MS = 30_000
RECORD_VIOLATIONS = """
window.cspViolations = [];
document.addEventListener("securitypolicyviolation", (event) => {
  window.cspViolations.push(`${event.violatedDirective} ${event.blockedURI} ${event.sourceFile}`);
});
"""
"""Runs before the page's own scripts (Playwright's init scripts are not the page's)."""


@pytest.fixture
def urv1(router_endpoint: str) -> Iterator[None]:
    """URV1 powered up on bologna-ring, standing (its status feeds the charts)."""
    with open_session(ZenohSettings(connect=(router_endpoint,))) as session:
        node = OnboardNode(
            OnboardSettings(vehicle_id="URV1"),
            session=session,
            clock=RealTimeClock(5.0),
            track_map=TrackMap(load_seed_line("bologna-ring")),
        )
        runner = threading.Thread(target=node.run, daemon=True)
        runner.start()
        yield
        node.stop()
        runner.join(5.0)
        node.close()


def _visit_every_view(page: Any, console_url: str) -> None:
    from playwright.sync_api import expect

    page.goto(console_url)
    page.fill("input[name=username]", ADMIN[0])
    page.fill("input[name=password]", ADMIN[1])
    page.click("button[type=submit]")
    expect(page.locator("tr[data-vehicle=URV1]")).to_be_visible(timeout=WAIT_MS)
    expect(page.locator("#connection")).to_have_text("live")  # the fleet WebSocket
    page.click("a[data-open=URV1]")
    expect(page.locator("#connection")).to_have_text("live", timeout=WAIT_MS)
    page.wait_for_function(
        "() => { const g = document.querySelector('#chart-time');"
        " return g.data && g.data[0].x.length > 0; }",
        timeout=WAIT_MS,
    )
    page.click("#select-vehicle")
    expect(page.locator("#driver-holder")).to_have_text(f"held by {ADMIN[0]}")
    lease = re.compile(r"^lease to \d\d:\d\d:\d\d$")
    expect(page.locator("#driver-lease")).to_have_text(lease)
    # The console's session socket renews the hold and names it in the header.
    expect(page.locator("#holding")).to_contain_text("holding URV1 (lease to", timeout=WAIT_MS)
    page.click("a[data-nav=fleet]")
    holder = page.locator("tr[data-vehicle=URV1] td[data-field=lease]")
    expect(holder).to_have_text(re.compile(r"^\d\d:\d\d:\d\d$"), timeout=WAIT_MS)
    page.click("a[data-nav=planner]")
    page.select_option("#planner-line", "bologna-ring")
    page.wait_for_function(
        "() => { const g = document.querySelector('#planner-chart');"
        " return g.data && g.data.some((t) => t.name === 'MRSP'); }",
        timeout=WAIT_MS,
    )
    page.goto(f"{console_url}#/report/URV1")
    expect(page.locator("#report-panel")).to_be_visible()


@pytest.mark.usefixtures("urv1")
def test_the_console_runs_under_its_content_security_policy(
    console_url: str, chromium: Any, artefacts: Artefacts
) -> None:
    page = chromium.new_page(viewport={"width": 1400, "height": 1000})
    page.add_init_script(RECORD_VIOLATIONS)
    messages: list[str] = []

    def on_console(message: Any) -> None:
        if not message.location.get("url", "").endswith("/favicon.ico"):  # the console has none
            messages.append(f"{message.type}: {message.text}")

    page.on("console", on_console)
    page.on("pageerror", lambda error: messages.append(f"pageerror: {error}"))
    socket_urls: list[str] = []
    page.on("websocket", lambda socket: socket_urls.append(socket.url))
    response = page.goto(console_url)
    assert response is not None
    assert "script-src 'self'" in response.headers["content-security-policy"]
    _visit_every_view(page, console_url)
    artefacts.screenshot(page, "report-under-csp")
    violations = page.evaluate("() => window.cspViolations")
    assert violations == [], violations
    assert not [text for text in messages if "Content Security Policy" in text], messages
    assert not [text for text in messages if text.startswith(("error", "pageerror"))], messages
    assert socket_urls
    assert all("token" not in url for url in socket_urls), socket_urls
