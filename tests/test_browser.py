"""A real browser opens the pages: headless Chromium (the system's, driven by playwright)
loads a replay written by ``rgmcad simulate --html`` and a report written for an optimisation
run, from disk, and we look at what it shows.

The page's clock is playwright's (``page.clock``): the replay advances only when a test runs
the clock forward, so what a test sees does not depend on how busy the machine is (a replay
that had played to its end under load once failed an assertion on a playing one).

Skipped only when no Chromium is found (tests/_browsers.py), and then the run ends with one
line saying how to install one; under CI (``CI`` set) a missing browser fails instead.
"""

import contextlib
import io
import time

import numpy as np
import pytest

from rgmcad.cli import main
from rgmcad.scene.loader import load_scenario
from tests._browsers import launched_browser

playwright = pytest.importorskip("playwright.sync_api", reason="playwright is not installed "
                                 "(uv sync installs it with the dev dependencies)")

SIMPLE = "scenarios/simple.toml"
READY_WITHIN_MS = 120_000
"""How long a page may take to be ready before the test fails: generous, a busy machine with
software GL is slow, and the figure is printed, not asserted."""


@pytest.fixture(scope="module")
def browser():
    yield from launched_browser()


@contextlib.contextmanager
def _open(browser, path):
    """The page at ``path`` once its viewer is ready, and the seconds that took; its clock is
    playwright's, stopped: time passes in it only by ``page.clock.run_for`` (every frame) or
    ``fast_forward`` (one frame, the time jumped)."""
    page = browser.new_page(viewport={"width": 1000, "height": 800})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    try:
        page.clock.install(time=0)
        page.clock.pause_at(1000)  # stopped: no frame is drawn unless a test runs the clock
        start = time.perf_counter()
        page.goto(path.resolve().as_uri())
        page.wait_for_selector("#rgmcad-replay[data-ready='1']", timeout=READY_WITHIN_MS)
        took = time.perf_counter() - start
        page.clock.run_for(100)  # a few frames drawn
        assert not errors, errors
        yield page, took
    finally:
        page.close()  # a page left open keeps animating, and slows the next ones


def _canvas(page) -> np.ndarray:
    from PIL import Image

    png = page.locator("#rgmcad-replay canvas").screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), float)


def _viewer(page, call: str):
    return page.evaluate(f"window.rgmcadViewer.{call}")


@pytest.fixture(scope="module")
def replay(tmp_path_factory):
    out = tmp_path_factory.mktemp("replay") / "simple.html"
    assert main(["simulate", SIMPLE, "--layout", "solved", "--html", str(out)]) == 0
    return out


def test_the_3d_view_is_drawn(browser, replay):
    with _open(browser, replay) as (page, took):
        print(f"replay of simple opened in {took:.2f} s")
        _viewer(page, "pause()")
        image = _canvas(page)
        assert image.shape[0] > 200 and image.shape[1] > 300
        colours = len(np.unique(image.reshape(-1, 3), axis=0))
        assert image.std() > 10 and colours > 50  # shaded, not a blank or flat canvas
        # the moving parts are drawn in colour; the floor, grid and background are grey
        saturation = image.max(axis=2) - image.min(axis=2)
        assert (saturation > 60).mean() > 0.002


def test_two_screenshots_a_second_apart_differ_while_playing(browser, replay):
    with _open(browser, replay) as (page, _):
        page.uncheck("#rgmcad-replay .loop")  # no wrapping round to the same picture
        page.click("#rgmcad-replay .speed >> text='1/10x'")  # the run lasts 5.8 s of playing
        _viewer(page, "seek(0)")
        _viewer(page, "play()")
        page.clock.run_for(50)
        first, t_first = _canvas(page), _viewer(page, "time()")
        page.clock.fast_forward(1000)  # one frame, a second later
        second, t_second = _canvas(page), _viewer(page, "time()")
        assert t_second > t_first and _viewer(page, "playing()")
        assert np.abs(first - second).max() > 50
        page.click("#rgmcad-replay .play")  # pause: the picture stands still
        assert not _viewer(page, "playing()")
        page.clock.run_for(50)
        still, t_still = _canvas(page), _viewer(page, "time()")
        page.clock.fast_forward(1000)
        assert _viewer(page, "time()") == t_still
        assert np.array_equal(still, _canvas(page))


def test_slow_motion_plays_at_a_tenth_of_real_time(browser, replay):
    with _open(browser, replay) as (page, _):
        page.uncheck("#rgmcad-replay .loop")
        page.click("#rgmcad-replay .speed >> text='1/10x'")
        _viewer(page, "seek(0)")
        _viewer(page, "play()")
        page.clock.run_for(100)  # the first frame after play() only starts the count
        t0 = _viewer(page, "time()")
        page.clock.fast_forward(2000)
        advanced = _viewer(page, "time()") - t0
        assert advanced == pytest.approx(0.2, abs=0.004), advanced  # a frame is 16 ms
        page.click("#rgmcad-replay .speed >> text='1x'")
        t0 = _viewer(page, "time()")
        page.clock.fast_forward(200)
        assert _viewer(page, "time()") - t0 == pytest.approx(0.2, abs=0.04)


def _timeline(page) -> dict[str, str]:
    return page.evaluate("Object.fromEntries([...document.querySelectorAll('.events "
                         "[data-event]')].map(e => [e.dataset.event, e.className]))")


def test_the_timeline_lists_every_event_and_lights_them_in_turn(browser, replay):
    with _open(browser, replay) as (page, _):
        _viewer(page, "pause()")
        _viewer(page, "seek(0)")
        page.clock.run_for(100)
        events = load_scenario(SIMPLE).events
        at_start = _timeline(page)
        assert set(at_start) == set(events)
        assert not any("lit" in c for c in at_start.values())
        _viewer(page, f"seek({_viewer(page, 'duration')})")
        page.clock.run_for(100)
        assert all(c == "lit" for c in _timeline(page).values())  # solved: every event succeeds


def test_a_failed_event_turns_red(browser, tmp_path):
    scenario = load_scenario(SIMPLE)
    rng = np.random.default_rng(0)
    out = tmp_path / "failing.html"
    for _ in range(50):  # a layout whose chain breaks
        vector = ",".join(f"{v:.4f}" for v in rng.random(len(scenario.free)))
        main(["simulate", SIMPLE, "--vector", vector, "--html", str(out)])
        if out.exists() and 'data-state="failure"' in out.read_text():
            break
    else:
        pytest.fail("no failing layout among 50 random ones")
    with _open(browser, out) as (page, _):
        _viewer(page, "pause()")
        _viewer(page, f"seek({_viewer(page, 'duration')})")
        page.clock.run_for(100)
        states = page.evaluate("[...document.querySelectorAll('.events [data-event]')]"
                               ".map(e => [e.dataset.state, e.className])")
        assert any(s == "failure" for s, _ in states)
        assert all(("failed" in c) == (s == "failure") for s, c in states)


def test_the_optimisation_report_opens_with_its_replay_and_figures(browser, tmp_path):
    from rgmcad.runs.workflow import optimize_scenario
    from rgmcad.viewer.report import write_run_report
    from tests.test_optimize import TINY

    run = tmp_path / "run"
    optimize_scenario(SIMPLE, seed=3, budget="small", settings=TINY, run_dir=run, workers=1)
    with _open(browser, write_run_report(run, SIMPLE)) as (page, took):
        print(f"report opened in {took:.2f} s")
        _viewer(page, "pause()")
        assert _canvas(page).std() > 10
        assert set(_timeline(page)) == set(load_scenario(SIMPLE).events)
        widths = page.evaluate("[...document.querySelectorAll('figure img')].map(i => i.naturalWidth)")
        assert len(widths) == 3 and min(widths) > 300


def _drag(page, dy: float, button: str = "left") -> None:
    """Drag the mouse ``dy`` pixels up (down if negative) from the 3D view's centre."""
    box = page.locator("#rgmcad-replay canvas").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down(button=button)
    page.mouse.move(x, y - dy, steps=8)
    page.mouse.up(button=button)
    page.clock.run_for(50)


def _same_view(a: dict, b: dict) -> bool:
    return all(np.allclose(a[k], b[k], atol=1e-9) for k in ("position", "target", "up"))


def test_the_view_stays_above_the_floor_resets_and_names_the_parts(browser, replay):
    # one page for the camera, its reset and the names: a page load costs a second or more
    with _open(browser, replay) as (page, _):
        _viewer(page, "pause()")
        first = _viewer(page, "camera")
        floor = _viewer(page, "floor")
        assert floor == pytest.approx(0.0, abs=1e-9)  # simple's floor plane
        assert first["up"] == [0, 0, 1] and first["position"][2] > floor
        # an upward drag of 120 px once put the camera under the floor; orbiting, then
        # panning (right drag) either way, it stays above the floor, looking at or above it
        for dy, button in ((120, "left"), (300, "left"), (1000, "left"), (1000, "right"),
                           (-1000, "right"), (-300, "right")):
            _viewer(page, "resetView()")
            _drag(page, dy, button)
            camera = _viewer(page, "camera")
            assert camera["position"][2] > floor and camera["target"][2] >= floor - 1e-9, \
                (dy, button, camera)
        assert camera != first
        page.keyboard.press("r")  # the keyboard's reset
        page.clock.run_for(50)
        assert _same_view(_viewer(page, "camera"), first)
        _drag(page, 300)
        page.click("#rgmcad-replay .reset-view")  # and the button's
        page.clock.run_for(50)
        assert _same_view(_viewer(page, "camera"), first)

        # pointing at a part names it: the ball, and a domino of the run by its own name
        assert _viewer(page, "hovered()") is None
        for name in ("ball", "run[1]"):
            page.mouse.move(*_viewer(page, f"screenPoint({name!r})"))
            page.clock.run_for(50)
            assert _viewer(page, "hovered()") == name
            assert page.locator("#rgmcad-replay .hover-name").inner_text() == name
        # the names toggle: one tag per object, a domino run's once
        tags = "#rgmcad-replay .name-tags span"
        assert not page.locator(tags).first.is_visible()
        page.check("#rgmcad-replay .names")
        page.clock.run_for(50)
        assert sorted(page.locator(tags).all_inner_texts()) == ["ball", "run", "track"]
        assert all(page.locator(tags).nth(i).is_visible() for i in range(3))
        page.keyboard.press("n")
        page.clock.run_for(50)
        assert not _viewer(page, "namesShown()") and not page.locator(tags).first.is_visible()
