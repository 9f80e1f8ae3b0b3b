"""The report in a real browser: headless Chromium (Debian's ``chromium``) driven by Playwright.

Every image loads, no ``NaN``/``None`` text shows, the leaderboard is the first table, and
the page fits 1280 px without a horizontal scrollbar. CI installs the browser (``.ci/run``)
and the test fails there (``CI`` set) when it is missing; elsewhere it is skipped with the reason.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from simbench.report.build import finalize
from simbench.runs.compose import compose_config
from simbench.runs.jobs import run_job

#: Where Debian puts its Chromium; ``SIMBENCH_CHROMIUM`` overrides it.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")
VIEWPORT = {"width": 1280, "height": 900}


def _chromium() -> str:
    """The browser's path, or a failure in CI / a skip elsewhere naming what is missing."""
    path = os.environ.get("SIMBENCH_CHROMIUM") or next(filter(None, map(shutil.which, CHROMIUM_NAMES)), None)
    problem = ""
    if path is None:
        problem = "no chromium on PATH (apt-get install chromium, or set SIMBENCH_CHROMIUM)"
    else:
        try:
            import playwright.sync_api  # noqa: F401  # optional: only this test drives a browser
        except ImportError:
            problem = "the playwright package is missing (pip install -e '.[test]')"
    if problem:
        if os.environ.get("CI", "") not in ("", "0", "false"):
            pytest.fail(f"browser test cannot run in CI: {problem}", pytrace=False)
        pytest.skip(problem)
    assert path is not None
    return path


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    _chromium()  # before the run: a machine without a browser spends nothing on it
    root = tmp_path_factory.mktemp("browser") / "run"
    run_job(
        compose_config(["scenario.duration_s=30", "estimator=[l2,ekf_ins]", f"results_dir={root}", "progress=false"])
    )
    return finalize(root, None) / "index.html"


@pytest.fixture(scope="module")
def page(report: Path):
    from playwright.sync_api import sync_playwright  # optional: imported where the browser is known to exist

    with sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=_chromium(), args=["--no-sandbox"])
        tab = browser.new_page(viewport=VIEWPORT)
        tab.goto(report.as_uri())
        tab.wait_for_load_state("load")
        yield tab
        browser.close()


def test_every_image_loads(page) -> None:
    images = page.evaluate("Array.from(document.images).map(i => [i.getAttribute('src'), i.complete, i.naturalWidth])")
    assert len(images) >= 7  # ECDF, box, trajectory, E/N/U, signal, consistency, run time
    broken = [src for src, complete, width in images if not complete or width == 0]
    assert not broken, broken


def test_no_nan_or_none_text(page) -> None:
    text = page.inner_text("body")
    for word in ("NaN", "None", "nan", "undefined"):
        assert f" {word} " not in f" {text} ".replace("\n", " "), word


def test_the_leaderboard_is_the_first_table(page) -> None:
    first = page.evaluate("document.querySelector('table').id")
    assert first == "leaderboard-table"
    # only the provenance box comes before it
    assert (
        page.evaluate("document.querySelector('.provenance').compareDocumentPosition(document.querySelector('table'))")
        == 4
    )
    header = page.inner_text("#leaderboard-table tr")
    for column in ("estimator", "family", "horizontal median [m]", "3-D p95 [m]", "time per epoch [ms]"):
        assert column in header


def test_the_page_fits_1280_px_without_a_horizontal_scrollbar(page) -> None:
    width, client = page.evaluate("[document.documentElement.scrollWidth, document.documentElement.clientWidth]")
    assert client == VIEWPORT["width"] and width <= client


def test_the_contents_link_every_section(page) -> None:
    links = page.evaluate("Array.from(document.querySelectorAll('#contents a')).map(a => a.getAttribute('href'))")
    sections = page.evaluate("Array.from(document.querySelectorAll('h2[id], details[id]')).map(h => '#' + h.id)")
    assert links == sections and "#leaderboard" in links and len(links) >= 3, (links, sections)
    # the contents come before the leaderboard, after the provenance box
    order = page.evaluate(
        "document.querySelector('#contents').compareDocumentPosition(document.querySelector('table'))"
    )
    assert order == 4


def test_no_table_overflows_its_box(page) -> None:
    """A table wider than the page scrolls inside its box; no box reaches past the page's text column."""
    boxes = page.evaluate(
        """Array.from(document.querySelectorAll('table')).map(t => {
            const box = t.parentElement, r = box.getBoundingClientRect(), body = document.body.getBoundingClientRect();
            return [box.className, getComputedStyle(box).overflowX, t.scrollWidth, box.clientWidth,
                    r.right <= body.right + 1];
        })"""
    )
    assert boxes
    for cls, overflow, table_width, box_width, inside in boxes:
        assert cls == "scroll" and inside
        assert table_width <= box_width or overflow == "auto"
