"""Time the README's test command as a newcomer runs it: in a fresh clone of this checkout's
HEAD (its own environment, no built parts), optionally while CPU-bound processes run beside it,
several times in a row. Prints each run's wall time, its exit status and its ten slowest tests.

    uv run python tools/time_suite.py [--repeat 3] [--load-per-core 2] [--keep DIR] [-- ARGS]

ARGS after ``--`` go to pytest (e.g. ``-- -n 3`` to try another number of workers).

--load-per-core K starts K busy-looping Python processes per CPU for the whole measurement
(2 per core is the "busy machine" of the test-suite issue). The environment is synced first,
untimed; the first run then builds the parts (as a new user's does), later runs reuse them.
"""

import argparse
import multiprocessing
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _spin() -> None:
    while True:
        pass


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--load-per-core", type=int, default=0)
    ap.add_argument("--keep", metavar="DIR", help="clone here and keep it (default: a temporary "
                    "folder, removed afterwards)")
    ap.add_argument("pytest_args", nargs="*", help="passed to pytest (after --)")
    args = ap.parse_args()

    where = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="rgmcad-suite-"))
    clone = where / "rgmcad"
    if not clone.exists():
        subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True)
    hogs = [multiprocessing.Process(target=_spin, daemon=True)
            for _ in range(args.load_per_core * (os.cpu_count() or 1))]
    for h in hogs:
        h.start()
    head = subprocess.check_output(["git", "-C", str(clone), "rev-parse", "--short", "HEAD"],
                                   text=True).strip()
    print(f"clone {clone} at {head}; {os.cpu_count()} CPUs; {len(hogs)} busy processes beside "
          "the suite", flush=True)
    failed = 0
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "RGMCAD_CACHE")}
    start = time.monotonic()
    subprocess.run(["uv", "sync", "--quiet"], cwd=clone, check=True, env=env)
    print(f"uv sync: {time.monotonic() - start:.0f} s (not counted below)", flush=True)
    try:
        for k in range(args.repeat):
            start = time.monotonic()
            done = subprocess.run(["uv", "run", "pytest", "--durations=10", *args.pytest_args], cwd=clone,
                                  capture_output=True, text=True, env=env)
            wall = time.monotonic() - start
            lines = done.stdout.splitlines()
            summary = next((ln for ln in reversed(lines) if re.search(r"passed|failed", ln)), "")
            slowest = [ln for ln in lines if re.match(r"^\d+\.\d+s (call|setup|teardown) ", ln)]
            print(f"run {k + 1}: {wall:.0f} s wall, exit {done.returncode}: {summary.strip('= ')}")
            for ln in slowest[:10]:
                print(f"    {ln}")
            if done.returncode != 0:
                failed += 1
                print(done.stdout[-4000:], done.stderr[-2000:], sep="\n")
    finally:
        for h in hogs:
            h.kill()
        if not args.keep:
            shutil.rmtree(where, ignore_errors=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
