"""Save-to-picture latency and memory of ``rgmcad live``, per shipped scenario.

For each scenario, starts ``rgmcad live COPY --layout solved --no-browser --port 0`` on a copy
of the shipped file (its parts already built: run ``rgmcad build parts`` first), opens the page
in headless Chromium when one is found, then saves the copy ``--saves`` times (a comment line
added, then taken away: each save is read, checked, simulated and recorded again) and prints:

* server: from the file event to the result ready to push (the state's ``took``: the
  watcher, 50 ms of quiet, loading, the validity test, the recorded simulation, the page);
* picture: from the save to the new picture shown (the viewer's frame ready in the page), on
  the page's own clock; headless Chromium draws with software GL, slower than a desktop's.

Then, on the scenarios of ``--memory``, the resident memory of the server and of its worker
after the first picture and after every tenth of ``--memory-saves`` saves (no page open).

    uv run python tools/live_latency.py [--saves 10] [--scenarios simple,teapot]
        [--memory simple,teapot] [--memory-saves 100] [--no-browser]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ("simple", "ballrun", "branching", "causality_switch", "long_chain", "teapot")
FLAGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox"]
MARK = """() => {
  window.__pictures = [];
  new MutationObserver(() => window.__pictures.push(performance.now()))
    .observe(document.body, {attributes: true, attributeFilter: ['data-picture']});
}"""


class Live:
    def __init__(self, folder: Path, name: str):
        self.file = folder / f"{name}.toml"
        shutil.copy(ROOT / "scenarios" / f"{name}.toml", self.file)
        self.text = self.file.read_text()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "rgmcad.cli", "live", str(self.file), "--layout", "solved",
             "--no-browser", "--port", "0"], cwd=folder, stdout=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline()
        self.url = line.split(" at ")[1].split()[0]
        self.wait(lambda s: s.get("view", 0) >= 1 and not s["busy"])

    def state(self) -> dict:
        with urllib.request.urlopen(self.url + "state", timeout=30) as r:
            return json.loads(r.read())

    def wait(self, ok, timeout: float = 120) -> dict:
        deadline = time.monotonic() + timeout
        while not ok(s := self.state()):
            if time.monotonic() > deadline:
                raise TimeoutError(s)
            time.sleep(0.01)
        return s

    def save(self, i: int) -> None:
        self.file.write_text(self.text + ("# saved again\n" if i % 2 == 0 else ""))

    def memory(self) -> tuple[float, float]:
        """Resident MiB of the server and of its worker (multiprocessing's helper left out)."""
        server = psutil.Process(self.proc.pid)
        workers = [p for p in server.children()
                   if "resource_tracker" not in " ".join(p.cmdline())]
        return (server.memory_info().rss / 2**20,
                sum(p.memory_info().rss for p in workers) / 2**20)

    def stop(self) -> None:
        self.proc.send_signal(2)
        self.proc.wait(timeout=30)


def _chromium() -> str | None:
    given = os.environ.get("RGMCAD_CHROMIUM")
    return given or next((p for p in map(shutil.which, ("chromium", "chromium-browser",
                                                        "google-chrome")) if p), None)


def latency(name: str, saves: int, browser) -> str:
    took, shown = [], []
    with tempfile.TemporaryDirectory() as folder:
        live = Live(Path(folder), name)
        page = None
        try:
            if browser is not None:
                page = browser.new_page(viewport={"width": 1300, "height": 950})
                page.goto(live.url)
                page.wait_for_selector("body[data-picture]:not([data-picture='0'])",
                                       timeout=120_000)
                page.evaluate(MARK)
            for i in range(saves):
                before = live.state()["generation"]
                if page is not None:
                    picture = page.get_attribute("body", "data-picture")
                    t0 = page.evaluate("() => performance.now()")
                live.save(i)
                s = live.wait(lambda s, b=before: s["generation"] > b and not s["busy"])
                took.append(s["took"])
                if page is not None:
                    page.wait_for_selector(f"body:not([data-picture='{picture}'])",
                                           timeout=120_000)
                    shown.append((page.evaluate("() => window.__pictures.at(-1)") - t0) / 1000)
            outcome = s["main"]["outcome"] if s.get("main") else s["error"]["text"]
        finally:
            if page is not None:
                page.close()
            live.stop()
    row = (f"{name:17s} {outcome:8s} server {statistics.median(took):5.2f} s "
           f"(max {max(took):4.2f})")
    if shown:
        row += f"   picture {statistics.median(shown):5.2f} s (max {max(shown):4.2f})"
    return row


def memory(name: str, saves: int) -> str:
    with tempfile.TemporaryDirectory() as folder:
        live = Live(Path(folder), name)
        try:
            marks = [(0, *live.memory())]
            for i in range(saves):
                before = live.state()["generation"]
                live.save(i)
                live.wait(lambda s, b=before: s["generation"] > b and not s["busy"])
                if (i + 1) % max(saves // 10, 1) == 0:
                    marks.append((i + 1, *live.memory()))
        finally:
            live.stop()
    first, last = marks[0], marks[-1]
    most = max(m[1] + m[2] for m in marks)
    return (f"{name:17s} after 0 saves: server {first[1]:4.0f} MiB, worker {first[2]:4.0f} MiB; "
            f"after {last[0]}: {last[1]:4.0f} + {last[2]:4.0f} MiB; most {most:.0f} MiB in all ("
            + ", ".join(f"{n}: {s + w:.0f}" for n, s, w in marks) + ")")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--saves", type=int, default=10)
    parser.add_argument("--scenarios", default=",".join(SCENARIOS))
    parser.add_argument("--memory", default="simple")
    parser.add_argument("--memory-saves", type=int, default=100)
    parser.add_argument("--no-browser", action="store_true")
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cores, load "
          f"{os.getloadavg()[0]:.1f}; {args.saves} saves each")
    path = None if args.no_browser else _chromium()
    if path is None:
        print("no page opened (no Chromium found, or --no-browser): server times only")
        rows = [latency(n, args.saves, None) for n in args.scenarios.split(",") if n]
    else:
        from playwright.sync_api import sync_playwright

        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=path, args=FLAGS)
            rows = [latency(n, args.saves, browser) for n in args.scenarios.split(",") if n]
            browser.close()
    print("\n".join(rows))
    for name in filter(None, args.memory.split(",")):
        print(memory(name, args.memory_saves))


if __name__ == "__main__":
    main()
