"""The journey planner in Debian's chromium against a live trackside: pick a line, add timing
points, validate (one infeasible leg, then a feasible plan), save, and see the line's profile;
and the same on a line imported into the trackside, drawn as a map with its stopping points."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.browser.conftest import ADMIN, CHROMIUM, Artefacts
from tests.deploy.valley_line import valley_line
from trackdb import Line, parse_line

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


@dataclass(frozen=True)
class ImportedLine:
    """A line imported into the trackside, and a journey with two intermediate stops on it."""

    line: Line
    start_m: float
    cap_kmh: float
    timing_points: tuple[tuple[str, int, int | None], ...]
    """(stopping point, arrival [s], departure [s]) of each timing point."""


RAILJSON = (
    Path(__file__).resolve().parents[2] / "deploy" / "lines" / "junction-valley.railjson.json"
)


def _import_railjson(console_url: str, headers: dict[str, str], database: Path) -> Line:
    """``ato trackdb import --format railjson`` into the running trackside's database; the
    line as the trackside serves it."""
    command = [sys.executable, "-m", "deploy", "trackdb", "import", str(RAILJSON)]
    command += ["--format", "railjson", "--from", "westbrook", "--to", "eastfield"]
    command += ["--via", "millbridge", "--via", "valley-junction", "--id", "junction-valley"]
    command += ["--database", f"sqlite:///{database}"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    with httpx.Client(base_url=console_url) as client:
        stored = client.get("/api/v1/lines/junction-valley", headers=headers)
    assert stored.status_code == 200, stored.text
    return parse_line(stored.content)


def _import_own_line(console_url: str, headers: dict[str, str]) -> Line:
    """A line of our own format through ``POST /api/v1/lines`` (admin)."""
    line = valley_line()
    with httpx.Client(base_url=console_url) as client:
        imported = client.post(
            "/api/v1/lines",
            content=line.model_dump_json(),
            headers=headers | {"Content-Type": "application/json"},
        )
    assert imported.status_code == 201, imported.text
    return line


def _admin_headers(console_url: str) -> dict[str, str]:
    with httpx.Client(base_url=console_url) as client:
        answer = client.post(
            "/api/v1/auth/token", data={"username": ADMIN[0], "password": ADMIN[1]}
        )
    return {"Authorization": f"Bearer {answer.json()['access_token']}"}


@pytest.mark.parametrize("source", ["railjson", "own-format"])
def test_planner_draws_an_imported_line_and_saves_a_journey_on_it(
    console_url: str, chromium: Any, artefacts: Artefacts, tmp_path: Path, source: str
) -> None:
    """A line imported into the trackside (not a built-in: RailJSON through ``ato trackdb
    import --format railjson`` into its database, or our format through REST) is drawn: its map
    from the geodetic polyline with its stopping points, its speed and gradient profiles; a
    journey with two intermediate stops is validated and saved on it."""
    from playwright.sync_api import expect

    headers = _admin_headers(console_url)
    if source == "railjson":
        # The console fixture's trackside runs on tmp_path / "ts.db" (tests/browser/conftest.py).
        line = _import_railjson(console_url, headers, tmp_path / "ts.db")
        case = ImportedLine(
            line,
            300.0,
            80.0,
            (("millbridge", 240, 270), ("valley-junction", 520, 550), ("eastfield", 800, None)),
        )
    else:
        line = _import_own_line(console_url, headers)
        case = ImportedLine(line, 100.0, 60.0, (("a", 150, 170), ("b", 330, 350), ("c", 530, None)))

    page = chromium.new_page(viewport={"width": 1400, "height": 1400})
    page.goto(console_url)
    page.fill("input[name=username]", ADMIN[0])
    page.fill("input[name=password]", ADMIN[1])
    page.click("button[type=submit]")
    expect(page.locator("#fleet-panel")).to_be_visible()
    page.click("a[data-nav=planner]")
    expect(page.locator("#planner-panel")).to_be_visible()
    page.select_option("#planner-line", line.id)

    track = page.locator(f"#planner-map svg[data-line='{line.id}'] polyline[data-map=track]")
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

    journey_id = f"{line.id}-journey"
    page.fill("#planner-id", journey_id)
    page.fill("#planner-start", str(case.start_m))
    page.locator("#planner-start").dispatch_event("change")
    expect(page.locator("#planner-map [data-map=start]")).to_have_attribute(
        "data-chainage-m", f"{case.start_m:.1f}"
    )
    page.fill("#planner-max", str(case.cap_kmh))
    for row, (stop_id, arrival_s, departure_s) in enumerate(case.timing_points, start=1):
        _timing_point(page, row, stop_id, arrival_s, departure_s)
    page.click("#planner-validate")
    result = page.locator("#planner-result")
    expect(result).to_have_text("valid")
    expect(page.locator("#planner-legs tr[data-leg]")).to_have_count(3)
    page.click("#planner-save")
    expect(result).to_have_text(re.compile(rf"^saved {journey_id} version 1$"))
    artefacts.screenshot(page, f"planner-{source}")

    with httpx.Client(base_url=console_url) as client:
        stored = client.get(f"/api/v1/journeys/{journey_id}", headers=headers)
    assert stored.status_code == 200, stored.text
    journey = stored.json()["journey"]
    assert journey["line_id"] == line.id
    assert journey["start_position_m"] == pytest.approx(case.start_m)
    stops = [tp["stopping_point_id"] for tp in journey["timing_points"]]
    assert stops == [stop_id for stop_id, _, _ in case.timing_points]
