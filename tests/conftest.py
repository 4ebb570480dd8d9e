"""Hermetic part cache: tests (and the commands they start, which inherit the environment)
cache built parts in the checkout's ``build/parts``, never in the user's cache folder."""

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

os.environ["RGMCAD_CACHE"] = str(ROOT / "build" / "parts")


def pytest_terminal_summary(terminalreporter):
    """One visible line when the browser tests were skipped for want of a browser: the README's
    test command would otherwise pass without ever opening the pages it advertises."""
    skipped = [r for r in terminalreporter.stats.get("skipped", [])
               if r.nodeid.startswith("tests/test_browser.py")]
    if skipped:
        from tests._browsers import INSTALL

        terminalreporter.write_line(
            f"browser tests: {len(skipped)} skipped, no Chromium found; install one: {INSTALL}",
            yellow=True, bold=True)
