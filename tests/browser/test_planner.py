"""The journey planner in Debian's chromium against a live trackside: pick a line, add timing
points, validate (one infeasible leg, then a feasible plan), save, and see the line's profile;
and the same on a line imported into the trackside, drawn as a map with its stopping points."""

from __future__ import annotations

import re
import shutil
from typing import Any

import httpx
import pytest

from tests.browser.conftest import ADMIN, CHROMIUM, Artefacts
from tests.deploy.valley_line import valley_line

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


def test_planner_draws_an_imported_line_and_saves_a_journey_on_it(
    console_url: str, chromium: Any, artefacts: Artefacts
) -> None:
    """A line imported into the trackside (REST, as admin; not a built-in) is drawn: its map
    from the geodetic polyline with its stopping points, its speed and gradient profiles; a
    journey with two intermediate stops is validated and saved on it."""
    from playwright.sync_api import expect

    line = valley_line()
    with httpx.Client(base_url=console_url) as client:
        answer = client.post(
            "/api/v1/auth/token", data={"username": ADMIN[0], "password": ADMIN[1]}
        )
        headers = {"Authorization": f"Bearer {answer.json()['access_token']}"}
        headers["Content-Type"] = "application/json"
        imported = client.post("/api/v1/lines", content=line.model_dump_json(), headers=headers)
        assert imported.status_code == 201, imported.text

    page = chromium.new_page(viewport={"width": 1400, "height": 1400})
    page.goto(console_url)
    page.fill("input[name=username]", ADMIN[0])
    page.fill("input[name=password]", ADMIN[1])
    page.click("button[type=submit]")
    expect(page.locator("#fleet-panel")).to_be_visible()
    page.click("a[data-nav=planner]")
    expect(page.locator("#planner-panel")).to_be_visible()
    page.select_option("#planner-line", line.id)

    track = page.locator("#planner-map svg[data-line='valley-test'] polyline[data-map=track]")
    expect(track).to_have_attribute("data-points", str(len(line.geodetic)))
    drawn = track.get_attribute("points") or ""
    assert len(drawn.split()) == len(line.geodetic)
    for stop in line.stopping_points:
        expect(page.locator(f"#planner-map [data-map-stop='{stop.id}']")).to_contain_text(stop.name)
    page.wait_for_function(
        "() => { const g = document.querySelector('#planner-chart');"
        " return g.data && ['MRSP', 'gradient [‰]', 'stopping points']"
        ".every((name) => g.data.some((t) => t.name === name)); }"
    )
    # The map is the line's shape: its first and last points are the ends of the polyline.
    ends = page.evaluate(
        "() => { const p = document.querySelector('#planner-map polyline').points;"
        " return [p.getItem(0).x, p.getItem(0).y, p.getItem(p.numberOfItems - 1).x,"
        " p.getItem(p.numberOfItems - 1).y]; }"
    )
    assert ends[:2] != ends[2:]

    page.fill("#planner-id", "valley-journey")
    page.fill("#planner-start", "100")
    page.locator("#planner-start").dispatch_event("change")
    expect(page.locator("#planner-map [data-map=start]")).to_have_attribute(
        "data-chainage-m", "100.0"
    )
    page.fill("#planner-max", "60")
    _timing_point(page, 1, "a", 150, 170)
    _timing_point(page, 2, "b", 330, 350)
    _timing_point(page, 3, "c", 530, None)
    page.click("#planner-validate")
    result = page.locator("#planner-result")
    expect(result).to_have_text("valid")
    expect(page.locator("#planner-legs tr[data-leg]")).to_have_count(3)
    page.click("#planner-save")
    expect(result).to_have_text(re.compile(r"^saved valley-journey version 1$"))
    artefacts.screenshot(page, "planner-imported-line")

    with httpx.Client(base_url=console_url) as client:
        stored = client.get("/api/v1/journeys/valley-journey", headers=headers)
    assert stored.status_code == 200, stored.text
    journey = stored.json()
    assert journey["journey"]["line_id"] == "valley-test"
    stops = [tp["stopping_point_id"] for tp in journey["journey"]["timing_points"]]
    assert stops == ["a", "b", "c"]
