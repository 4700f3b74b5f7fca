"""The journey planner in Debian's chromium against a live trackside: pick a line, add timing
points, validate (one infeasible leg, then a feasible plan), save, and see the line's profile."""

from __future__ import annotations

import re
import shutil
from typing import Any

import pytest

from tests.browser.conftest import ADMIN, CHROMIUM, Artefacts

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="Debian's chromium is not installed"),
]


def _timing_point(page: Any, row: int, stop: str, arrival_s: int, departure_s: int | None) -> None:
    page.click("#planner-add-tp")
    cells = page.locator(f"#planner-tps tr[data-timing-point='{row}']")
    cells.locator("[data-tp=id]").fill(stop)
    cells.locator("[data-tp=stop]").select_option(stop)
    cells.locator("[data-tp=arrival]").fill(str(arrival_s))
    if departure_s is not None:
        cells.locator("[data-tp=departure]").fill(str(departure_s))


def test_planner_validates_saves_and_plots_a_journey(
    console_url: str, chromium: Any, artefacts: Artefacts
) -> None:
    from playwright.sync_api import expect

    page = chromium.new_page(viewport={"width": 1400, "height": 1000})
    page.goto(console_url)
    page.fill("input[name=username]", ADMIN[0])
    page.fill("input[name=password]", ADMIN[1])
    page.click("button[type=submit]")
    expect(page.locator("#fleet-panel")).to_be_visible()
    page.click("a[data-nav=planner]")
    expect(page.locator("#planner-panel")).to_be_visible()
    page.select_option("#planner-line", "bologna-ring")
    page.wait_for_function(
        "() => { const g = document.querySelector('#planner-chart');"
        " return g.data && g.data.some((t) => t.name === 'MRSP'); }"
    )
    page.fill("#planner-id", "planned-lap")
    page.fill("#planner-start", "200")
    _timing_point(page, 1, "east", 10, 30)  # 10 s cannot reach the east platform
    _timing_point(page, 2, "south", 550, None)
    page.click("#planner-validate")
    result = page.locator("#planner-result")
    expect(result).to_have_attribute("data-ok", "false")
    expect(result).to_contain_text("not valid")
    expect(page.locator("#planner-legs tr[data-leg]")).to_have_count(2)

    page.locator("#planner-tps tr[data-timing-point='1'] [data-tp=arrival]").fill("300")
    page.locator("#planner-tps tr[data-timing-point='1'] [data-tp=departure]").fill("320")
    page.click("#planner-validate")
    expect(result).to_have_text("valid")
    page.click("#planner-save")
    expect(result).to_have_text(re.compile(r"^saved planned-lap version 1$"))
    artefacts.screenshot(page, "planner")
