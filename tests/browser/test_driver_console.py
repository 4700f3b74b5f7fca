"""The driver console in Debian's chromium against live trackside + onboard (issue 9, "must show").

A person logs in, selects URV1, answers the Vital Control's power-up requests (vigilance, EB
rearm), drives in RD to the balise group that brings FS, stops, sends the ``bologna-ring``
journey and sees it acknowledged, engages AD, sees the speed rise on the chart, answers a
vigilance prompt, presses EB and sees the train stop and the VC state change. The onboard runs on
a RealTimeClock at 5× so that the run is short; every answer to the VC is a click in the page.
"""

from __future__ import annotations

import re
import shutil
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import httpx
import pytest

from deploy.scenario.loader import load_scenario
from onboard.node import OnboardNode, OnboardSettings
from onboard.runtime import RealTimeClock
from onboard.vc.config import VcConfig
from protocol import ZenohSettings, open_session
from tests.browser.conftest import ADMIN, CHROMIUM, Artefacts
from trackdb import TrackMap, load_seed_line

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian's chromium is not installed"),
]

SPEED_UP = 5.0
CONSOLE_VC = VcConfig(vigilance_period_s=120.0, vigilance_timeout_s=100.0)
"""Vigilance asked at power-up and every 120 s of simulated time; 100 s to answer (20 s of wall
time at 5×), so a person (the test) has room to click on a loaded machine."""
WAIT_MS = 30_000
"""Upper bound for one step to show in the page; the steps are much faster when things work."""
ENGAGE_ATTEMPTS = 5


@dataclass
class Vehicle:
    node: OnboardNode
    runner: threading.Thread

    def start(self) -> None:
        """Power up: the VC's power-up requests start their timeouts now."""
        self.runner.start()


@pytest.fixture
def urv1(router_endpoint: str) -> Iterator[Vehicle]:
    """URV1 on bologna-ring, nobody answering its Vital Control but the console's user. The
    test powers it up once the page is there (a browser may take seconds to start)."""
    with open_session(ZenohSettings(connect=(router_endpoint,))) as session:
        node = OnboardNode(
            OnboardSettings(vehicle_id="URV1", vc_config=CONSOLE_VC),
            session=session,
            clock=RealTimeClock(SPEED_UP),
            track_map=TrackMap(load_seed_line("bologna-ring")),
        )
        vehicle = Vehicle(node, threading.Thread(target=node.run, daemon=True))
        yield vehicle
        node.stop()
        if vehicle.runner.is_alive():
            vehicle.runner.join(5.0)
        node.close()


def _field(page: Any, name: str) -> Any:
    return page.locator(f'#driver-panel [data-field="{name}"]')


def _chart_speeds_kmh(page: Any) -> list[float]:
    """The speed trace as plotted (Plotly keeps the figure's data on its div)."""
    values = page.evaluate(
        "() => { const g = document.querySelector('#chart-time');"
        " return g && g.data ? g.data[0].y.filter((v) => v !== null) : []; }"
    )
    return [float(value) for value in values]


def _log_in(page: Any, console_url: str) -> None:
    page.goto(console_url)
    page.fill("input[name=username]", ADMIN[0])
    page.fill("input[name=password]", ADMIN[1])
    page.click("button[type=submit]")


def _create_journey(base_url: str, start_m: float) -> None:
    """The journey of the ``bologna-ring`` scenario (seed 000's field test), stored under the
    name ``bologna-ring`` from where the train stands (what the planner does through REST)."""
    journey = load_scenario("bologna-ring").journey
    assert journey is not None
    assert journey.max_speed_kmh is not None
    body = {
        "id": "bologna-ring",
        "line_id": "bologna-ring",
        "start_position_m": start_m,
        "max_speed_mps": journey.max_speed_kmh / 3.6,
        "timing_points": [point.model_dump(mode="json") for point in journey.timing_points],
    }
    with httpx.Client(base_url=base_url) as client:
        login = client.post("/api/v1/auth/token", data={"username": ADMIN[0], "password": ADMIN[1]})
        headers = {"Authorization": f"Bearer {login.json()['access_token']}"}
        response = client.post("/api/v1/journeys", json=body, headers=headers)
        assert response.status_code == 201, response.text


def _engage(page: Any) -> None:
    """Press Engage once ATO is ready; the person presses again if the vehicle refused (its
    readiness may lapse for a status period, e.g. while the trackside session is renewed)."""
    from playwright.sync_api import expect

    answer = page.locator("#command-answer")
    for _attempt in range(ENGAGE_ATTEMPTS):
        expect(_field(page, "ato-state")).to_have_text("RE", timeout=WAIT_MS)
        page.click("#engage")
        expect(answer).to_have_attribute("data-accepted", re.compile("^(true|false)$"))
        if answer.get_attribute("data-accepted") == "true":
            return
    pytest.fail(f"engage refused {ENGAGE_ATTEMPTS} times: {answer.inner_text()}")


def test_driver_console_drives_urv1_through_the_field_sequence(
    console_url: str, urv1: Vehicle, chromium: Any, artefacts: Artefacts
) -> None:
    from playwright.sync_api import expect

    page = chromium.new_page(viewport={"width": 1400, "height": 1100})
    _log_in(page, console_url)
    expect(page.locator("#fleet-panel")).to_be_visible(timeout=WAIT_MS)
    urv1.start()
    expect(page.locator("tr[data-vehicle=URV1]")).to_be_visible(timeout=WAIT_MS)
    page.click("a[data-open=URV1]")
    expect(page.locator("#driver-panel")).to_be_visible()
    expect(page.locator("#connection")).to_have_text("live")  # the per-vehicle WebSocket
    expect(page.locator("#simulated-operator")).to_have_attribute("data-simulated", "false")
    expect(_field(page, "etcs-mode")).to_have_text(re.compile(r"^(SR|FS)$"), timeout=WAIT_MS)
    expect(page.locator("#track-strip [data-station=east]")).to_have_count(1)
    expect(page.locator("#track-strip [data-balise]").first).to_be_attached()
    # Power-up: the VC holds the EB and asks for vigilance and for the EB rearm.
    expect(_field(page, "vc-eb")).to_have_text("APPLIED", timeout=WAIT_MS)
    prompt = page.locator("#vigilance-prompt")
    expect(prompt).to_be_visible(timeout=WAIT_MS)
    expect(page.locator("#vigilance-countdown")).to_have_text(re.compile(r"^\d+\.\d$"))
    expect(page.locator("[data-request=eb_rearm]")).to_be_visible()
    page.wait_for_function("() => document.querySelector('#chart-time').data !== undefined")
    artefacts.screenshot(page, "power-up")

    page.click("#select-vehicle")
    expect(page.locator("#driver-holder")).to_have_text(f"held by {ADMIN[0]}")
    page.click("#vigilance-ack")
    expect(page.locator("#request-answer")).to_have_text("vigilance-ack: accepted")
    expect(prompt).to_be_hidden(timeout=WAIT_MS)
    page.click("[data-confirm=eb_rearm]")
    expect(_field(page, "vc-eb")).to_have_text("released", timeout=WAIT_MS)
    # From now on the person answers every vigilance prompt as it comes.
    page.add_locator_handler(prompt, lambda: page.click("#vigilance-ack"))

    page.fill("#rd-speed", "30")
    page.click("#rd-send")
    expect(page.locator("#command-answer")).to_have_attribute("data-accepted", "true")
    expect(_field(page, "etcs-mode")).to_have_text("FS", timeout=WAIT_MS)
    page.fill("#rd-speed", "0")
    page.click("#rd-send")
    expect(_field(page, "vc-standstill")).to_have_text("yes", timeout=WAIT_MS)
    artefacts.screenshot(page, "stopped-in-fs")

    _create_journey(console_url, float(urv1.node.track_map.normalise(urv1.node.plant.position_m)))
    page.click("#journeys-reload")
    expect(page.locator("#journey-select option[value=bologna-ring]")).to_have_count(1)
    page.select_option("#journey-select", "bologna-ring")
    page.click("#send-journey")
    acknowledged = re.compile(r"journey bologna-ring v1: acknowledged")
    expect(page.locator("#journey-answer")).to_have_text(acknowledged, timeout=WAIT_MS)
    answer = page.locator("#command-answer")
    _engage(page)
    expect(_field(page, "ato-state")).to_have_text("EG", timeout=WAIT_MS)
    expect(_field(page, "sc-state")).to_have_text("AD", timeout=WAIT_MS)

    before = max(_chart_speeds_kmh(page)[-5:], default=0.0)
    page.wait_for_function(
        "(floor) => { const g = document.querySelector('#chart-time');"
        " const y = g && g.data ? g.data[0].y : []; return y.length && y[y.length - 1] > floor; }",
        arg=before + 5.0,
        timeout=WAIT_MS,
    )
    assert max(_chart_speeds_kmh(page)) > before + 5.0
    artefacts.screenshot(page, "engaged-speed-rising")

    page.click("#emergency-brake")
    expect(answer).to_have_text("emergency-brake: accepted", timeout=WAIT_MS)
    expect(_field(page, "vc-eb")).to_have_text("APPLIED", timeout=WAIT_MS)
    expect(_field(page, "vc-brake")).not_to_have_text("released")
    expect(_field(page, "vc-standstill")).to_have_text("yes", timeout=WAIT_MS)
    expect(_field(page, "speed")).to_have_text("0.0 km/h", timeout=WAIT_MS)
    confirmed = page.locator('#event-log tr[data-code="operator.confirm.vigilance"]')
    expect(confirmed.first).to_be_attached(timeout=WAIT_MS)
    artefacts.screenshot(page, "emergency-brake")

    # The run report: seed 000 figs. 9–10 from the 1 Hz telemetry history.
    page.click("#report-link")
    expect(page.locator("#report-panel")).to_be_visible()
    expect(page.locator("#report-message")).to_have_attribute("data-samples", re.compile(r"^[1-9]"))
    for chart in ("#report-speed", "#report-error", "#report-traction"):
        page.wait_for_function(f"() => document.querySelector('{chart}').data !== undefined")
    traction = page.evaluate("() => document.querySelector('#report-traction').data[0].y")
    assert max(traction) > 0.0  # kN drawn while the train accelerated
    artefacts.screenshot(page, "run-report")
