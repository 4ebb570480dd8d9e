"""Install rgmcad from its wheel alone into a fresh virtual environment and use it from
another directory, as a user who ran ``pip install rgmcad`` would.

    uv run python tools/check_wheel.py [--keep]

Builds the wheel (``uv build``), makes a virtual environment in a temporary folder, installs
the wheel there, then, from an empty working directory: ``rgmcad simulate simple --json`` (a
shipped scenario by name) must succeed, ``--html`` must write a replay page holding the
vendored three.js, ``rgmcad check ballrun`` must list the shipped
layouts, and ``rgmcad build parts --out parts-out`` must write a manifest of every shipped
part. Prints one line per check; exits 1 if one fails.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run(cmd, cwd, env=None, timeout=1800):
    done = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    if done.returncode != 0:
        sys.stderr.write(done.stdout[-2000:] + done.stderr[-4000:])
    return done


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--keep", action="store_true", help="keep the temporary folder")
    args = parser.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="rgmcad-wheel-"))
    ok = True
    try:
        dist = tmp / "dist"
        if run(["uv", "build", "--wheel", "--out-dir", str(dist)], ROOT).returncode:
            return 1
        wheel = next(dist.glob("rgmcad-*.whl"))
        venv = tmp / "venv"
        if run(["uv", "venv", "--python", sys.executable, str(venv)], tmp).returncode:
            return 1
        env = {**os.environ, "VIRTUAL_ENV": str(venv)}
        env.pop("PYTHONPATH", None)
        if run(["uv", "pip", "install", "--python", str(venv / "bin" / "python"), str(wheel)],
               tmp, env).returncode:
            return 1
        rgmcad = str(venv / "bin" / "rgmcad")
        work = tmp / "elsewhere"
        work.mkdir()

        def check(name, passed):
            nonlocal ok
            ok &= bool(passed)
            print(f"{'ok  ' if passed else 'FAIL'} {name}")

        done = run([rgmcad, "simulate", "simple", "--json"], work, env)
        out = [line for line in done.stdout.splitlines() if line.startswith("{")]
        check("rgmcad simulate simple (shipped scenario by name, from another directory)",
              done.returncode == 0 and out and json.loads(out[-1])["outcome"] == "success")
        done = run([rgmcad, "simulate", "simple", "--html", "replay.html"], work, env)
        page = work / "replay.html"
        check("rgmcad simulate simple --html (the viewer's three.js and assets are packaged)",
              done.returncode == 0 and page.exists()
              and "Three.js Authors" in page.read_text() and "rgmcadViewer" in page.read_text())
        done = run([rgmcad, "check", "ballrun"], work, env)
        check("rgmcad check ballrun", done.returncode in (0, 1) and "solved: valid" in done.stdout)
        done = run([rgmcad, "build", "parts", "--out", "parts-out"], work, env)
        manifest = work / "parts-out" / "manifest.json"
        parts = json.loads(manifest.read_text())["parts"] if manifest.exists() else []
        check(f"rgmcad build parts ({len(parts)} parts in the manifest)",
              done.returncode == 0 and len(parts) > 5)
        done = run([rgmcad, "simulate", str(ROOT / "scenarios" / "simple.toml")], work, env)
        check("a scenario file given by path", done.returncode == 0)
    finally:
        if args.keep:
            print(f"kept {tmp}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
