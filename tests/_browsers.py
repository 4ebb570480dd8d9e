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
