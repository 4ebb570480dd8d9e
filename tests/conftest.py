"""Hermetic part cache: tests (and the commands they start, which inherit the environment)
cache built parts in the checkout's ``build/parts``, never in the user's cache folder. Under
pytest-xdist the parts of every scenario file in the checkout are built first, by two
processes, before the test workers start: otherwise each worker builds the same parts at the
same moment in a fresh checkout (the store has no lock; both builds give the same files)."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

os.environ["RGMCAD_CACHE"] = str(ROOT / "build" / "parts")


def pytest_configure(config):
    if hasattr(config, "workerinput") or not config.getoption("numprocesses", None):
        return  # a worker (the controller built them), or one process building as it goes
    files = sorted(str(p) for d in ("scenarios", "tests/data", "tools/generality")
                   for p in (ROOT / d).glob("*.toml"))
    builds = [subprocess.Popen([sys.executable, "-m", "rgmcad.cli", "build", "parts", *half,
                                "-q"], cwd=ROOT, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
              for half in (files[0::2], files[1::2])]
    for b in builds:
        b.wait()  # a scenario that fails to build fails in its own tests, with the reason


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
