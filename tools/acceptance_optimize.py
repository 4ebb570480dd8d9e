"""Acceptance figures of `rgmcad optimize` (issue 3): for each scenario and seed, the
simulations and wall time of a default run, and rho_g (by `rgmcad evaluate`, same sample
count for all) of the optimised layout, of the best exploration sample (`start.json`) and of
the scenario's `solved` layout. Runs resume: an existing run or evaluation in OUT is reused,
so use a fresh OUT for other settings.

    uv run python tools/acceptance_optimize.py [--scenarios simple ballrun] [--seeds 0 1 2]
        [--samples 50] [--workers 2 | --scheduler ADDRESS|local:N] [--budget default]
        [--out acceptance]

About 5 min for `simple` and 15 min for `ballrun` on 2 cores (most of it in `evaluate`).
"""

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np


def rgmcad(*args: str) -> dict:
    """Run one CLI command with --json and return its JSON output."""
    out = subprocess.run([sys.executable, "-m", "rgmcad.cli", *args, "--json"],
                         capture_output=True, text=True)
    if out.returncode not in (0, 1):
        raise SystemExit(f"rgmcad {' '.join(args)} failed: {out.stderr.strip().splitlines()[-1:]}")
    return json.loads(out.stdout)


def cached(path: Path, *args: str) -> dict:
    """The JSON output of ``rgmcad ARGS``, kept in ``path`` (run once)."""
    if path.exists():
        return json.loads(path.read_text())
    value = rgmcad(*args)
    path.write_text(json.dumps(value))
    return value


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=["simple", "ballrun"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--samples", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="simulate on a Dask cluster (ADDRESS or local:N) instead of --workers")
    parser.add_argument("--budget", default="default")
    parser.add_argument("--out", default="acceptance")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    common = (["--scheduler", args.scheduler] if args.scheduler
              else ["--workers", str(args.workers)])
    evaluate = ["--samples", str(args.samples), "--seed", "0", *common]

    for name in args.scenarios:
        scenario = f"scenarios/{name}.toml"
        solved = cached(out / f"eval-{name}-solved.json", "evaluate", scenario, "--layout",
                        "solved", "--out", str(out / f"{name}-solved.png"), *evaluate)["rho_g"]
        rows = []
        for seed in args.seeds:
            run = out / f"{name}-s{seed}"
            summary = cached(out / f"{name}-s{seed}.json", "optimize", scenario, "--run",
                             str(run), "--seed", str(seed), "--budget", args.budget, *common)
            rho = {lay: cached(out / f"eval-{name}-s{seed}-{lay}.json", "evaluate", scenario,
                               "--layout", str(run / f"{lay}.json"), *evaluate)["rho_g"]
                   for lay in ("layout", "start")}
            rows.append((seed, summary, rho))
            print(f"{name} seed {seed}: {summary['simulations']} simulations, "
                  f"{summary['wall_time']:.1f} s, chosen: {summary['source']}; rho_g optimised "
                  f"{rho['layout']:.3f}, best exploration sample {rho['start']:.3f}")
        opt = np.mean([r[2]["layout"] for r in rows])
        start = np.mean([r[2]["start"] for r in rows])
        print(f"{name}: mean rho_g optimised {opt:.3f}, best exploration sample {start:.3f}, "
              f"solved {solved:.3f}: optimised {'beats' if opt > max(start, solved) else 'does NOT beat'}"
              " both\n")


if __name__ == "__main__":
    main()
