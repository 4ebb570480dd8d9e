"""Screenshots of the replay pages of the shipped scenarios and of one optimisation report,
for docs/ and the README, taken by headless Chromium (Debian's ``chromium``) through playwright.

    uv run python tools/screenshots.py [--out docs] [--chromium /usr/bin/chromium]

Writes ``replay-SCENARIO.png`` (the solved layout, paused at 60 % of the run) for every
shipped scenario and ``report-simple.png`` (``rgmcad optimize simple --budget small``).
"""

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from playwright.sync_api import sync_playwright

ROOT = Path(__file__).resolve().parent.parent
FLAGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox"]


def shoot(browser, page_path: Path, out: Path, *, full: bool, at: float = 0.6) -> None:
    page = browser.new_page(viewport={"width": 1000, "height": 760})
    page.goto(page_path.resolve().as_uri())
    page.wait_for_selector("#rgmcad-replay[data-ready='1']", timeout=60_000)
    page.evaluate(f"window.rgmcadViewer.pause(); "
                  f"window.rgmcadViewer.seek(window.rgmcadViewer.duration * {at})")
    page.wait_for_timeout(300)
    if full:
        page.screenshot(path=str(out), full_page=True)
    else:
        page.locator("#rgmcad-replay").screenshot(path=str(out))
    page.close()
    print(f"{out} ({out.stat().st_size // 1024} KiB)")


def rgmcad(*args: str, cwd: Path) -> None:
    subprocess.run([sys.executable, "-m", "rgmcad.cli", "--build-dir", str(ROOT / "build"), *args],
                   cwd=cwd, check=True, stdout=subprocess.DEVNULL)


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default=str(ROOT / "docs"))
    parser.add_argument("--chromium", default=shutil.which("chromium") or "chromium")
    args = parser.parse_args()
    out = Path(args.out)
    tmp = Path(tempfile.mkdtemp(prefix="rgmcad-shots-"))
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=args.chromium, args=FLAGS)
            for scenario in sorted((ROOT / "scenarios").glob("*.toml")):
                html = tmp / f"{scenario.stem}.html"
                rgmcad("simulate", str(scenario), "--layout", "solved", "--html", str(html),
                       cwd=tmp)
                shoot(browser, html, out / f"replay-{scenario.stem}.png", full=False)
            run = tmp / "run-simple"
            rgmcad("optimize", str(ROOT / "scenarios" / "simple.toml"), "--budget", "small",
                   "--run", str(run), "--workers", "1", cwd=tmp)
            shoot(browser, run / "report.html", out / "report-simple.png", full=True)
            browser.close()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
