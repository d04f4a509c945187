"""The web page of ``shapedb serve`` in a real browser: Debian's headless chromium via selenium.

Skipped, with the reason, where selenium, chromium or its driver is missing. Screenshots
go to a temporary folder (or ``$SHAPEDB_SCREENSHOTS``) and are named in the log.
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi", reason="the serve extra is not installed")

from server_helpers import build_store, live_server  # noqa: E402

from query.serve.server import create_app  # noqa: E402

log = logging.getLogger(__name__)

CHROME_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--enable-unsafe-swiftshader",  # software WebGL for this trusted local page
    "--window-size=1280,900",
]

# A copy of the canvas arguments[0]'s pixels: d (RGBA bytes), c (its width and height).
_READ = """
const c = document.createElement('canvas');
c.width = arguments[0].width; c.height = arguments[0].height;
const ctx = c.getContext('2d');
ctx.drawImage(arguments[0], 0, 0);
const d = ctx.getImageData(0, 0, c.width, c.height).data;
const ink = (i) => d[i] < 235 || d[i + 1] < 235 || d[i + 2] < 235;
"""

# Pixels of a canvas that are not (nearly) white, and those that are the highlight red.
PIXELS = (
    _READ
    + """
let n = 0;
for (let i = 0; i < d.length; i += 4) {
  const [r, g, b] = [d[i], d[i + 1], d[i + 2]];
  if (arguments[1] === 'red' ? (r > 150 && g < 90 && b < 90) : ink(i)) n++;
}
return n;
"""
)

# The box of a canvas's non-white pixels, as fractions of its width and height.
INK_BOX = (
    _READ
    + """
let [x0, y0, x1, y1] = [c.width, c.height, -1, -1];
for (let y = 0; y < c.height; y++) for (let x = 0; x < c.width; x++) {
  if (ink(4 * (y * c.width + x))) {
    x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
  }
}
return x1 < 0 ? [0, 0] : [(x1 - x0 + 1) / c.width, (y1 - y0 + 1) / c.height];
"""
)

# The mean brightness (0-255) of a canvas's non-white pixels, and how many there are.
INK_MEAN = (
    _READ
    + """
let [n, sum] = [0, 0];
for (let i = 0; i < d.length; i += 4) if (ink(i)) { n++; sum += (d[i] + d[i + 1] + d[i + 2]) / 3; }
return [n ? sum / n : 255, n];
"""
)

# Counts the WebGL contexts the page makes, and keeps them to see which are still active.
COUNT_CONTEXTS = """
window.__webgl = [];
const getContext = HTMLCanvasElement.prototype.getContext;
HTMLCanvasElement.prototype.getContext = function (type, ...rest) {
  const ctx = getContext.call(this, type, ...rest);
  if (ctx && type.startsWith('webgl') && !window.__webgl.includes(ctx)) window.__webgl.push(ctx);
  return ctx;
};
"""
ACTIVE_CONTEXTS = "return window.__webgl.filter((g) => !g.isContextLost()).length"

#: Thumbnail files (name -> modification time, ns) of the test store as ingest left them.
BUILT_THUMBNAILS: dict[str, int] = {}


def _browser_or_skip() -> tuple[str, str]:
    try:
        import selenium  # noqa: F401
    except ImportError:
        pytest.skip("no browser: selenium is not installed (dev extra)")
    chromium = next(
        (p for p in map(shutil.which, ("chromium", "chromium-browser")) if p is not None), None
    )
    driver = shutil.which("chromedriver")
    if chromium is None or driver is None:
        pytest.skip("no browser: install Debian's chromium and chromium-driver (.ci/setup)")
    return chromium, driver


@pytest.fixture(scope="module")
def shots(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = os.environ.get("SHAPEDB_SCREENSHOTS")
    path = Path(folder) if folder else tmp_path_factory.mktemp("screenshots")
    path.mkdir(parents=True, exist_ok=True)
    return path


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Any, dict[str, Path]]]:
    chromium, _ = _browser_or_skip()
    db, models = build_store(tmp_path_factory.mktemp("browser"))
    for png in (db.path / "thumbnails").rglob("*.png"):
        BUILT_THUMBNAILS[png.name] = png.stat().st_mtime_ns
    with live_server(create_app(db)) as url:
        yield url, db, models


@pytest.fixture(scope="module")
def browser(site: Any) -> Iterator[Any]:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    chromium, driver = _browser_or_skip()
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    profile = tempfile.mkdtemp(prefix="shapedb-chromium-")
    for flag in [*CHROME_FLAGS, f"--user-data-dir={profile}"]:
        options.add_argument(flag)
    options.set_capability("goog:loggingOptions", {"browser": "ALL"})
    d = webdriver.Chrome(service=Service(driver), options=options)
    d.set_page_load_timeout(60)
    d.execute_cdp_cmd("Page.addScriptToEvaluateOnNewDocument", {"source": COUNT_CONTEXTS})
    try:
        yield d
    finally:
        d.quit()
        shutil.rmtree(profile, ignore_errors=True)


def _wait(d: Any, condition: Any, seconds: float = 120) -> Any:
    from selenium.webdriver.support.ui import WebDriverWait

    return WebDriverWait(d, seconds, poll_frequency=0.2).until(condition)


def _shot(d: Any, folder: Path, name: str) -> Path:
    path = folder / f"{name}.png"
    d.save_screenshot(str(path))
    log.warning("screenshot %s", path)
    return path


def _canvas(d: Any, view: str) -> Any:
    from selenium.webdriver.common.by import By

    return d.find_element(By.CSS_SELECTOR, f"#{view} canvas")


@pytest.fixture(scope="module")
def page(browser: Any, site: Any) -> Any:
    url, _, _ = site
    browser.get(url + "/")
    _wait(browser, lambda d: d.execute_script("return !!(window.shapedb && window.shapedb.ready)"))
    return browser


def test_the_page_loads(page, shots):
    from selenium.webdriver.common.by import By

    assert page.title == "shapedb"
    assert page.find_element(By.ID, "store-summary").text.startswith("6 shapes")
    assert (
        page.execute_script("return document.querySelectorAll('#shape-names option').length") == 6
    )
    severe = [e for e in page.get_log("browser") if e["level"] == "SEVERE"]
    assert severe == []
    _shot(page, shots, "01-loaded")


def test_a_card_shows_a_placeholder_until_its_thumbnail_loads(page, shots, monkeypatch):
    from selenium.webdriver.common.by import By

    from query import thumbnails
    from shapedb.errors import NotFoundError

    def not_yet(root: Any, record: Any) -> Any:
        raise NotFoundError("no thumbnail yet", source=record.id)

    monkeypatch.setattr(thumbnails, "thumbnail", not_yet)  # the server runs in this process
    box = page.find_element(By.ID, "pick-name")
    box.clear()
    box.send_keys("box1")
    page.find_element(By.CSS_SELECTOR, "#pick button").click()
    _wait(page, lambda d: len(d.find_elements(By.CSS_SELECTOR, "#results .card")) == 6)
    cards = page.find_elements(By.CSS_SELECTOR, "#results .card")
    for card in cards:
        name = card.find_element(By.CSS_SELECTOR, ".name").text
        holder = card.find_element(By.CSS_SELECTOR, ".placeholder")
        assert holder.is_displayed() and name in holder.text
        grey = page.execute_script("return getComputedStyle(arguments[0]).backgroundColor", holder)
        assert grey not in ("rgba(0, 0, 0, 0)", "rgb(255, 255, 255)"), grey
    _shot(page, shots, "01b-placeholders")
    monkeypatch.undo()  # the thumbnails come: the page asks again and they replace the boxes
    _wait(
        page,
        lambda d: d.execute_script(
            "return [...document.querySelectorAll('#results .pic')]"
            ".every(p => !p.classList.contains('loading') && p.querySelector('img').naturalWidth)"
        ),
        30,
    )
    assert not any(c.find_element(By.CSS_SELECTOR, ".placeholder").is_displayed() for c in cards)


@pytest.fixture(scope="module")
def searched(page: Any, site: Any) -> Any:
    from selenium.webdriver.common.by import By

    _, _, models = site
    page.find_element(By.ID, "file").send_keys(str(models["capsule1"]))
    title = "Nearest to capsule1.obj"
    _wait(page, lambda d: d.find_element(By.ID, "results-title").text == title)
    _wait(page, lambda d: len(d.find_elements(By.CSS_SELECTOR, "#results .card")) == 6)
    _wait(  # every thumbnail drawn and loaded
        page,
        lambda d: d.execute_script(
            "return [...document.querySelectorAll('#results img')]"
            ".every(i => i.complete && i.naturalWidth > 0)"
        ),
    )
    return page


def test_an_uploaded_model_gets_results_and_its_3d_view_draws(searched, shots):
    from selenium.webdriver.common.by import By

    names = [e.text for e in searched.find_elements(By.CSS_SELECTOR, "#results .card .name")]
    assert names[0] == "capsule1" and sorted(names) == sorted(
        ["box0", "box1", "capsule0", "capsule1", "cylinder0", "cylinder1"]
    )
    assert searched.find_element(By.ID, "results-title").text == "Nearest to capsule1.obj"
    canvas = _canvas(searched, "query-view")
    assert searched.execute_script(PIXELS, canvas, "ink") > 2000  # the query is drawn
    _shot(searched, shots, "02-results")


def test_results_show_thumbnails_drawn_when_the_shapes_were_committed(searched, site):
    from selenium.webdriver.common.by import By

    _, db, _ = site
    assert len(BUILT_THUMBNAILS) == 6  # drawn by the ingest's commit, before any page view
    now = {p.name: p.stat().st_mtime_ns for p in (db.path / "thumbnails").rglob("*.png")}
    assert now == BUILT_THUMBNAILS  # none drawn (again) when the results were shown
    images = searched.find_elements(By.CSS_SELECTOR, "#results .card img")
    assert len(images) == 6 and all(i.is_displayed() for i in images)


def test_the_query_fills_its_3d_view(searched):
    _wait(searched, lambda d: d.execute_script(PIXELS, _canvas(d, "query-view"), "ink") > 2000)
    width, height = searched.execute_script(INK_BOX, _canvas(searched, "query-view"))
    assert max(width, height) > 0.75, (width, height)


def test_a_part_click_highlights_matches(searched, shots):
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    Select(searched.find_element(By.ID, "hops")).select_by_value("1")
    canvas = _canvas(searched, "query-view")
    x, y = searched.execute_script("return window.shapedb.queryView.screenOf(0)")
    rect = searched.execute_script("return arguments[0].getBoundingClientRect().toJSON()", canvas)
    dx = round(x - rect["left"] - rect["width"] / 2)
    dy = round(y - rect["top"] - rect["height"] / 2)
    ActionChains(searched).move_to_element_with_offset(canvas, dx, dy).click().perform()
    _wait(searched, lambda d: len(d.find_elements(By.CSS_SELECTOR, "#results .card.matched")) == 6)
    cards = searched.find_elements(By.CSS_SELECTOR, "#results .card.matched canvas")
    red = [searched.execute_script(PIXELS, c, "red") for c in cards]
    assert min(red) > 50, red  # every result shows its matched part in red
    assert searched.execute_script(PIXELS, canvas, "red") > 50  # and the query its part
    status = searched.find_element(By.ID, "status").text
    assert "matched in 6 results" in status
    time.sleep(0.2)
    _shot(searched, shots, "03-part-match")


def test_a_click_beside_the_balls_says_so(searched):
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    canvas = _canvas(searched, "query-view")
    rect = searched.execute_script("return arguments[0].getBoundingClientRect().toJSON()", canvas)
    corner = (round(-rect["width"] / 2 + 6), round(-rect["height"] / 2 + 6))
    ActionChains(searched).move_to_element_with_offset(canvas, *corner).click().perform()
    _wait(searched, lambda d: "no ball there" in d.find_element(By.ID, "status").text, 10)
    assert "click on a ball" in searched.find_element(By.ID, "status").text


def test_one_webgl_context_checks_the_browser(searched):
    # the two views and the shared renderer of the matched parts, and one check (released)
    made = searched.execute_script("return window.__webgl.length")
    assert made <= 4, made
    assert searched.execute_script(ACTIVE_CONTEXTS) <= 3
    logs = [e["message"] for e in searched.get_log("browser")]
    assert not [m for m in logs if "Too many active WebGL contexts" in m]


def test_clicking_a_result_opens_its_3d_view(searched, shots):
    from selenium.webdriver.common.by import By

    second = searched.find_elements(By.CSS_SELECTOR, "#results .card")[1]
    name = second.find_element(By.CSS_SELECTOR, ".name").text
    second.click()
    _wait(searched, lambda d: d.find_element(By.ID, "shape-panel").is_displayed())
    _wait(searched, lambda d: name in d.find_element(By.ID, "panel-title").text)
    _wait(searched, lambda d: d.execute_script(PIXELS, _canvas(d, "shape-view"), "ink") > 2000)
    toggles = searched.find_elements(By.CSS_SELECTOR, "#shape-panel .toggles input")
    assert [t.get_attribute("data-layer") for t in toggles] == ["surface", "balls", "graph"]
    toggles[2].click()  # the contact graph on
    assert searched.execute_script("return window.shapedb.shapeView.current.graph.visible") is True
    time.sleep(0.5)  # the surface arrives after the balls
    _shot(searched, shots, "04-result-3d")
    searched.find_element(By.ID, "panel-close").click()
    assert not searched.find_element(By.ID, "shape-panel").is_displayed()


def test_browser_facets_and_evaluation(searched, shots):
    from selenium.webdriver.common.by import By

    searched.find_element(By.CSS_SELECTOR, ".tab[data-tab='browse']").click()
    _wait(searched, lambda d: len(d.find_elements(By.CSS_SELECTOR, "#facets li")) == 4)
    facets = [li.text.split("\n") for li in searched.find_elements(By.CSS_SELECTOR, "#facets li")]
    assert facets == [["all", "6"], ["box", "2"], ["capsule", "2"], ["cylinder", "2"]]
    searched.find_elements(By.CSS_SELECTOR, "#facets li")[2].click()
    _wait(searched, lambda d: len(d.find_elements(By.CSS_SELECTOR, "#browse-grid .card")) == 2)
    _shot(searched, shots, "05-browse")
    searched.find_element(By.CSS_SELECTOR, ".tab[data-tab='evaluate']").click()
    searched.find_element(By.ID, "run-eval").click()
    _wait(searched, lambda d: len(d.find_elements(By.CSS_SELECTOR, "#eval-table tr")) == 4)
    assert searched.find_element(By.ID, "eval-status").text == "6 queries"
    assert searched.find_elements(By.CSS_SELECTOR, "#pr-curve polyline")
    _shot(searched, shots, "06-evaluate")


def test_the_openapi_page_renders(browser, site, shots):
    from selenium.webdriver.common.by import By

    url, _, _ = site
    browser.get(url + "/docs")
    _wait(browser, lambda d: len(d.find_elements(By.CSS_SELECTOR, ".opblock")) >= 14)
    assert "/api/search" in browser.find_element(By.TAG_NAME, "body").text
    _shot(browser, shots, "07-openapi")


def test_ingest_by_upload_with_progress(searched, site, shots, tmp_path_factory):
    import trimesh
    from selenium.webdriver.common.by import By

    path = tmp_path_factory.mktemp("upload") / "slab.obj"
    trimesh.creation.box((3, 2, 0.3)).export(path)
    searched.get(site[0] + "/")  # back from the OpenAPI page
    _wait(searched, lambda d: d.execute_script("return !!(window.shapedb && window.shapedb.ready)"))
    searched.find_element(By.CSS_SELECTOR, ".tab[data-tab='browse']").click()
    searched.find_element(By.ID, "ingest-files").send_keys(str(path))
    searched.find_element(By.ID, "ingest-label").send_keys("slab")
    searched.find_element(By.CSS_SELECTOR, "#ingest-form button").click()
    _wait(searched, lambda d: "ingested 1" in d.find_element(By.ID, "ingest-status").text)
    _wait(searched, lambda d: "slab\n1" in d.find_element(By.ID, "facets").text)
    assert searched.find_element(By.ID, "store-summary").text.startswith("7 shapes")
    assert site[1].store.resolve("slab") > 0
    _shot(searched, shots, "08-ingested")


def test_picking_a_stored_shape_searches_it(searched, shots):
    from selenium.webdriver.common.by import By

    searched.find_element(By.CSS_SELECTOR, ".tab[data-tab='search']").click()
    box = searched.find_element(By.ID, "pick-name")
    box.clear()
    box.send_keys("box1")
    searched.find_element(By.CSS_SELECTOR, "#pick button").click()
    _wait(searched, lambda d: d.find_element(By.ID, "results-title").text == "Nearest to box1")
    first = searched.find_elements(By.CSS_SELECTOR, "#results .card .name")[0].text
    assert first == "box1"
    _wait(searched, lambda d: d.execute_script(PIXELS, _canvas(d, "query-view"), "ink") > 2000)
    _shot(searched, shots, "09-stored-query")


def test_the_surface_is_solid_when_the_balls_are_hidden(searched, shots):
    from selenium.webdriver.common.by import By

    view = "return window.shapedb.queryView.current"
    _wait(searched, lambda d: d.execute_script(view + ".surface !== null"))  # box1's mesh
    balls = searched.find_element(
        By.CSS_SELECTOR, ".toggles[data-for='query-view'] [data-layer='balls']"
    )
    balls.click()  # balls off
    assert searched.execute_script(view + ".balls.visible") is False
    canvas = _canvas(searched, "query-view")
    mean, ink = searched.execute_script(INK_MEAN, canvas)
    assert ink > 5000 and mean < 150, (mean, ink)  # the box drawn solid, not a faint veil
    assert searched.execute_script(view + ".surface.material.opacity") == 1
    _shot(searched, shots, "10-surface-only")
    balls.click()
