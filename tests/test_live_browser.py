"""The live page in a real browser: headless Chromium (the system's, driven by playwright, as
in tests/test_browser.py) on a real ``rgmcad live``. A save on disk shows its outcome, a
broken file its error line and a fixed one its picture again; a slider gives the outcome
the sweep said it would; two layouts side by side both play.

Skipped only when no Chromium is found (tests/_browsers.py); under CI a missing browser fails.
The default run opens one page (a save, a broken file, a fix); the slider and side-by-side
tests are slow ones (``-m slow``).
"""

from __future__ import annotations

import io
import time

import numpy as np
import pytest

from tests._browsers import launched_browser
from tests._live import BROKEN, FAILING, TRACK, Server
from tests._support import cli_output

playwright = pytest.importorskip("playwright.sync_api", reason="playwright is not installed "
                                 "(uv sync installs it with the dev dependencies)")

WITHIN_MS = 60_000
"""How long the page may take to show a change before the test fails: generous (software
GL on a busy machine); the times are printed, and tools/live_latency.py measures them."""


@pytest.fixture(scope="module")
def browser():
    yield from launched_browser()


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    s = Server(tmp_path_factory.mktemp("live-browser"))
    yield s
    s.stop()


@pytest.fixture
def page(browser, server):
    """The live page of simple as shipped, its first picture shown."""
    server.write(server.original)
    p = browser.new_page(viewport={"width": 1300, "height": 950})
    errors = []
    p.on("pageerror", lambda e: errors.append(str(e)))
    p.goto(server.url)
    p.wait_for_selector("body[data-picture]:not([data-picture='0'])", timeout=WITHIN_MS)
    try:
        yield p
        assert not errors, errors
    finally:
        p.close()


def _picture(page) -> int:
    return int(page.get_attribute("body", "data-picture"))


def _next_picture(page, after: int) -> float:
    """Wait for a picture newer than ``after``; the seconds it took."""
    start = time.perf_counter()
    # a selector, not a function: the page's policy allows no script from strings
    page.wait_for_selector(f"body:not([data-picture='{after}'])", timeout=WITHIN_MS)
    return time.perf_counter() - start


def _viewer(page):
    return page.frame_locator("iframe.front")


def _camera(page) -> dict:
    return _viewer(page).locator("body").evaluate("() => window.rgmcadViewer.camera")


def test_a_save_shows_its_outcome_a_broken_file_its_error_and_a_fix_recovers(page, server):
    shown = _picture(page)
    assert page.inner_text("#outcome") == "success"
    # the user turns the machine to look at it from another side, then saves: the new
    # picture keeps that camera (it once went back to the first framing at every save)
    framed = _camera(page)
    box = page.locator("iframe.front").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 160, y + 40, steps=8)
    page.mouse.up()
    page.wait_for_timeout(100)
    turned = _camera(page)
    assert not np.allclose(turned["position"], framed["position"], atol=1e-4)
    start = time.perf_counter()
    server.file.write_text(server.original.replace(TRACK, FAILING))
    _next_picture(page, shown)
    print(f"save to picture: {time.perf_counter() - start:.2f} s")
    assert page.inner_text("#outcome") == "failure"
    kept = _camera(page)
    assert np.allclose(kept["position"], turned["position"], atol=1e-6)
    assert np.allclose(kept["target"], turned["target"], atol=1e-6)
    _viewer(page).locator("body").evaluate("() => window.rgmcadViewer.resetView()")
    reset = np.asarray(_camera(page)["position"])  # this picture's own framing (its bounds
    assert (np.linalg.norm(reset - framed["position"])  # moved a little with the layout)
            < 0.2 * np.linalg.norm(reset - turned["position"]))
    assert "fails at last_dom_topples" in page.inner_text("#fails")
    failed = _viewer(page).locator(".events [data-state='failure']")
    assert failed.get_attribute("data-event") == "last_dom_topples"  # the viewer's own timeline
    assert page.locator("#events tr[data-state='failure']").inner_text().startswith(
        "last_dom_topples")

    shown = _picture(page)
    server.file.write_text(server.original + BROKEN)
    page.wait_for_selector("#error:not([hidden])", timeout=WITHIN_MS)
    code, _, err = cli_output(["check", str(server.file)])
    line = len(server.original.splitlines()) + 2
    assert code == 2 and page.inner_text("#error") == f"{err.strip()} (line {line})"
    assert page.get_attribute("body", "data-stale") == "1"  # the last picture stays, dimmed

    server.file.write_text(server.original)
    _next_picture(page, shown)
    assert page.is_hidden("#error") and page.inner_text("#outcome") == "success"


@pytest.mark.slow  # 5-10 s: a page and a sweep
def test_a_slider_gives_the_outcome_the_sweep_said(page):
    page.select_option("#sweep-name", "track.roll")
    page.fill("#sweep-points", "5")
    page.click("#sweep")
    page.wait_for_selector("body[data-sweep='done']", timeout=WITHIN_MS)
    cells = page.eval_on_selector_all("#sweep-strip button", "cells => cells.map(c => "
                                      "[Number(c.dataset.value), c.dataset.outcome])")
    assert [v for v, _ in cells] == [15.0, 30.0, 45.0, 60.0, 75.0]
    outcomes = {o for _, o in cells}
    assert {"success", "failure"} <= outcomes, cells
    for value, outcome in (next(c for c in cells if c[1] == "failure"),
                           next(c for c in cells if c[1] == "success")):
        shown = _picture(page)
        slider = page.locator(".slider[data-name='track.roll'] input[type=range]")
        slider.evaluate("(el, v) => { el.value = v; el.dispatchEvent(new Event('input')); "
                        "el.dispatchEvent(new Event('change')); }", value)  # let go at v
        _next_picture(page, shown)
        assert page.inner_text("#outcome") == outcome, (value, outcome)
        assert page.inner_text(".slider[data-name='track.roll'] .value") == f"{value:.2f} deg"


def _halves(page) -> tuple[np.ndarray, np.ndarray]:
    from PIL import Image

    png = _viewer(page).locator("#rgmcad-replay canvas").screenshot()
    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), float)
    middle = image.shape[1] // 2
    return image[:, :middle], image[:, middle:]


@pytest.mark.slow  # 5-10 s: a page and two layouts
def test_two_layouts_side_by_side_play_on_one_clock(page):
    shown = _picture(page)
    slider = page.locator(".slider[data-name='track.roll'] input[type=number]")
    slider.fill("60")
    slider.dispatch_event("change")
    _next_picture(page, shown)
    shown = _picture(page)
    page.select_option("#compare", "solved")
    _next_picture(page, shown)
    assert page.inner_text("#versus") == ("A (left): failure; B (right, solved): success")
    frame = _viewer(page)
    bodies = frame.locator("#rgmcad-replay-data").evaluate("e => JSON.parse(e.textContent)"
                                                            ".bodies.map(b => b.name)")
    assert {b.split(":")[0] for b in bodies} == {"A", "B"} and len(bodies) % 2 == 0
    viewer = page.frame_locator("iframe.front").locator("body")
    viewer.evaluate("() => { window.rgmcadViewer.pause(); window.rgmcadViewer.seek(0); }")
    page.wait_for_timeout(300)  # a few frames drawn
    before = _halves(page)
    viewer.evaluate("() => window.rgmcadViewer.seek(0.6)")  # one clock moves both
    page.wait_for_timeout(300)
    after = _halves(page)
    for left_or_right in (0, 1):
        changed = np.abs(after[left_or_right] - before[left_or_right]).max(axis=2) > 40
        assert changed.mean() > 0.001, left_or_right
    viewer.evaluate("() => window.rgmcadViewer.play()")
    t0 = viewer.evaluate("() => window.rgmcadViewer.time()")
    page.wait_for_timeout(500)
    assert viewer.evaluate("() => window.rgmcadViewer.time()") != t0
