"""The Energy Manager's figures on the web console (issue 22): the fleet row and the vehicle
page show the state of charge, the energy to go and the margin, a short margin as an alarm."""

from __future__ import annotations

import shutil
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from protocol import TypedPublisher, ZenohSettings, declare_liveliness, open_session
from protocol import messages as m
from protocol.registry import STATUS
from protocol.units import J_PER_KWH
from tests.browser.conftest import ADMIN, CHROMIUM, CHROMIUM_ARGS

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian's chromium is not installed"),
]

WAIT_MS = 10_000
PUBLISH_S = 0.2


def _report(short: bool) -> m.StatusReport:
    return m.StatusReport(
        vehicle_id="URV9",
        seq=0,
        sim_time_s=45.0,
        line_id="bologna-ring",
        position_m=186.0,
        speed_mps=0.0,
        acceleration_mps2=0.0,
        traction_force_n=0.0,
        ato_state=m.AtoState.READY,
        etcs_mode=m.EtcsMode.FS,
        sc_state=m.ScState.OFF,
        journey_id="low-energy",
        energy=m.EnergyStatus(
            soc=0.4743,
            energy_to_go_j=1.23 * J_PER_KWH,
            energy_available_j=1.07 * J_PER_KWH,
            margin_j=-0.16 * J_PER_KWH,
            range_extender_share=0.0,
            short=short,
            slowed=True,
        ),
    )


@contextmanager
def _publishing(router_endpoint: str, report: m.StatusReport) -> Iterator[None]:
    """A vehicle alive on the router that publishes ``report`` every :data:`PUBLISH_S`."""
    stop = threading.Event()
    with open_session(ZenohSettings(connect=(router_endpoint,))) as session:
        token = declare_liveliness(session, f"ato/alive/ob/{report.vehicle_id}")
        with TypedPublisher(session, STATUS, vehicle=report.vehicle_id) as publisher:

            def publish() -> None:
                while not stop.is_set():
                    publisher.put(report)
                    stop.wait(PUBLISH_S)

            worker = threading.Thread(target=publish, daemon=True)
            worker.start()
            try:
                yield
            finally:
                stop.set()
                worker.join(5.0)
                token.undeclare()


def test_the_console_shows_soc_energy_to_go_and_a_short_margin(
    router_endpoint: str, console_url: str, tmp_path: Path
) -> None:
    from playwright.sync_api import expect, sync_playwright

    with _publishing(router_endpoint, _report(short=True)), sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page()
        page.goto(console_url)
        page.fill("input[name=username]", ADMIN[0])
        page.fill("input[name=password]", ADMIN[1])
        page.click("button[type=submit]")
        row = page.locator("tr[data-vehicle=URV9]")
        expect(row).to_be_visible(timeout=WAIT_MS)
        expect(row.locator("td[data-field=soc]")).to_have_text("47.4", timeout=WAIT_MS)
        expect(row.locator("td[data-field=energy-to-go]")).to_have_text("1.23")
        margin = row.locator("td[data-field=energy-margin]")
        expect(margin).to_have_text("-0.16")
        expect(margin).to_have_class("num alarm")
        page.screenshot(path=str(tmp_path / "fleet-energy.png"))

        page.goto(f"{console_url}#/vehicle/URV9")
        field = page.locator('#driver-panel [data-field="energy-margin"]')
        expect(field).to_have_text("-0.16 kWh SHORT: do not engage", timeout=WAIT_MS)
        expect(field).to_have_attribute("data-alarm", "true")
        expect(page.locator('#driver-panel [data-field="soc"]')).to_have_text("47.4 %")
        expect(page.locator('#driver-panel [data-field="energy-to-go"]')).to_have_text("1.23 kWh")
        page.screenshot(path=str(tmp_path / "vehicle-energy.png"))
        browser.close()
