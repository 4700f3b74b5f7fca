"""The fleet page with 100 vehicles (issue 23, item 3): every one listed and kept up to date,
and the page still answers the operator while their reports stream in.

The vehicles are simulated: one process publishes 100 vehicles' liveliness and status reports
at 5 Hz over the test's router (``deploy.bench.trackside_bench.fleet_process``, the trackside
bench's fleet), as 100 onboards would; the trackside and the browser are the real ones. The
page's long tasks (main-thread work over 50 ms, Chromium's PerformanceObserver) are recorded as
a property of the test, not asserted: wall time is for benchmarks."""

from __future__ import annotations

import multiprocessing
import re
import shutil
from collections.abc import Callable

import pytest

from deploy.bench.trackside_bench import fleet_process
from tests.browser.conftest import ADMIN, CHROMIUM, CHROMIUM_ARGS, Artefacts

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian's chromium is not installed"),
]

VEHICLES = 100
FLEET_S = 60.0
"""How long the simulated fleet reports (the test ends it sooner)."""


def test_the_fleet_page_lists_100_vehicles_and_keeps_them_up_to_date(
    router_endpoint: str,
    console_url: str,
    artefacts: Artefacts,
    record_property: Callable[[str, object], None],
) -> None:
    from playwright.sync_api import expect, sync_playwright

    context = multiprocessing.get_context("spawn")
    ready = context.Event()
    fleet = context.Process(
        target=fleet_process, args=(router_endpoint, VEHICLES, FLEET_S, ready), daemon=True
    )
    fleet.start()
    try:
        assert ready.wait(30.0), "the simulated fleet did not start"
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            page = browser.new_page()
            page.add_init_script(
                "window.__longTasks = [];"
                "new PerformanceObserver(list => list.getEntries().forEach("
                "  e => window.__longTasks.push(e.duration))"
                ").observe({entryTypes: ['longtask']});"
            )
            page.goto(console_url)
            page.fill("input[name=username]", ADMIN[0])
            page.fill("input[name=password]", ADMIN[1])
            page.click("button[type=submit]")
            rows = page.locator("tr[data-vehicle^=SIM]")
            expect(rows).to_have_count(VEHICLES, timeout=20_000)
            expect(page.locator("#connection")).to_have_text("live")
            # Every one alive, and the first, middle and last kept up to date.
            expect(page.locator("tr[data-vehicle^=SIM].alive")).to_have_count(VEHICLES)
            for vehicle in ("SIM000", "SIM050", "SIM099"):
                position = page.locator(f"tr[data-vehicle={vehicle}] td[data-field=position]")
                expect(position).not_to_have_text(position.inner_text(), timeout=5_000)
            artefacts.screenshot(page, "fleet-100")
            # The operator opens the last vehicle's page while the reports stream in.
            page.locator("tr[data-vehicle=SIM099] a[data-open=SIM099]").click()
            expect(page).to_have_url(re.compile(r"#/vehicle/SIM099$"))
            # Reported (the JUnit report's properties), not judged.
            record_property("long_tasks_ms", sorted(page.evaluate("window.__longTasks")))
            browser.close()
    finally:
        fleet.terminate()
        fleet.join(10.0)
