"""The report opens in headless Chromium (Debian's, installed by ``make test``) from the
file, with no network: no console error, every image decoded and not blank, the page
itself not blank, no script run, the DUT's markup shown as text. ``BENCH_REPORT_DIR=reports``
runs the same checks on the main job's report."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from tests.report.suite import HOSTILE_NAME

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
         "--disable-component-update", "--disable-sync"]

# per image: decoded size, and the standard deviation of its pixels drawn on a canvas
IMAGES_JS = """() => Array.from(document.images).map(img => {
  const c = document.createElement('canvas');
  c.width = img.naturalWidth; c.height = img.naturalHeight;
  let sd = -1;
  if (img.complete && img.naturalWidth > 0) {
    const g = c.getContext('2d'); g.drawImage(img, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    let s = 0, s2 = 0, n = 0;
    for (let i = 0; i < d.length; i += 4 * 7) { const v = d[i] + d[i+1] + d[i+2]; s += v; s2 += v * v; n++; }
    sd = Math.sqrt(Math.max(0, s2 / n - (s / n) ** 2));
  }
  return {alt: img.alt, complete: img.complete, w: img.naturalWidth, h: img.naturalHeight, sd: sd};
})"""


@pytest.fixture(scope="module")
def browser():
    playwright = pytest.importorskip("playwright.sync_api")
    assert shutil.which("chromium"), "Chromium is missing: `make test` installs Debian's chromium package"
    with playwright.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=FLAGS)
        yield b
        b.close()


def test_the_report_opens_in_chromium_without_errors_and_every_image_shows(browser, report_dir, tmp_path):
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    problems: list[str] = []
    page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type in ("error", "warning")
            else None)
    page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
    page.on("requestfailed", lambda r: problems.append(f"request failed: {r.url}"))
    requests: list[str] = []
    page.on("request", lambda r: requests.append(r.url))
    page.goto((report_dir / "report.html").as_uri(), wait_until="load")
    images = page.evaluate(IMAGES_JS)
    assert problems == []
    assert all(u.startswith(("file:", "data:")) for u in requests), requests  # nothing from a network
    assert len(images) >= 4, "RPT-A and RPT-B have figures"
    for img in images:
        assert img["complete"] and img["w"] > 100 and img["h"] > 100, img
        assert img["sd"] > 5.0, f"blank image: {img['alt']}"
    assert page.evaluate("document.scripts.length") == 0
    if "RPT-A" in page.inner_text("#summary"):  # the report-test suite: its DUT's markup is text
        assert HOSTILE_NAME in page.inner_text("body")
    shot = tmp_path / "report.png"
    page.screenshot(path=str(shot), full_page=True)
    import matplotlib.image as mpimg

    pixels = mpimg.imread(shot)
    assert pixels.shape[0] > 2000 and float(np.std(pixels[..., :3])) > 0.05  # a long page with content
    page.close()


OVERFLOW_JS = """() => Array.from(document.querySelectorAll('table.criteria td'))
  .filter(td => td.scrollWidth > td.clientWidth + 1)
  .map(td => td.innerText.slice(0, 60))"""


def test_no_criteria_cell_spills_into_its_neighbour_at_the_width_of_a_printed_page(browser, report_dir):
    # A4 less the margins is about 690 CSS px: long ids and dotted metric names must break
    # inside their column (they ran over the value column in the PDF)
    page = browser.new_page(viewport={"width": 690, "height": 900})
    page.emulate_media(media="print")
    page.goto((report_dir / "report.html").as_uri(), wait_until="load")
    assert page.evaluate("document.querySelectorAll('table.criteria td').length") > 20
    assert page.evaluate(OVERFLOW_JS) == []
    page.close()
