"""Where the browser tests find a Chromium, and the one line that says how to install one when
none is found (printed at the end of every test run that skipped them: tests/conftest.py)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")

INSTALL = ("sudo apt-get install chromium (Debian, Ubuntu), or uv run playwright install "
           "chromium, or set RGMCAD_CHROMIUM to a Chromium or Chrome executable")


def chromium() -> str | None:
    """The Chromium to drive: ``RGMCAD_CHROMIUM``, else one on the PATH, else the one
    ``playwright install chromium`` downloaded; None when there is none."""
    given = os.environ.get("RGMCAD_CHROMIUM")
    if given:
        return given
    found = next((p for p in map(shutil.which, BROWSERS) if p), None)
    if found:
        return found
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        return None
    with sync_playwright() as p:
        path = p.chromium.executable_path
    return path if path and Path(path).is_file() else None


# software WebGL: a headless browser on a machine without a GPU
FLAGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox"]


def launched_browser():
    """A generator for a module fixture: the Chromium of :func:`chromium`, launched headless by
    playwright, closed after the module; the test is skipped where none is found (failed
    under CI, whose .ci/run installs one)."""
    import pytest
    from playwright.sync_api import sync_playwright

    path = chromium()
    if path is None:
        if os.environ.get("CI"):
            pytest.fail("no Chromium installed under CI: .ci/run should have installed it")
        pytest.skip(f"no Chromium found; install one: {INSTALL}")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=path, args=FLAGS)
        yield b
        b.close()
