"""Acceptance figures of `rgmcad optimize`: for each scenario and seed, the simulations and
wall time of a default run, and rho_g (by `rgmcad evaluate`, same sample count for all; under
placement errors and under placement plus physical errors) of the optimised layout, of the
best exploration sample (`start.json`) and of a reference layout of the scenario file
(`solved`, or e.g. `hand` for the held-out files in tools/generality/), each run's layouts
with their difference to the reference and its 95 % half-width (above, level or below). Runs
resume: an existing run or evaluation in OUT is reused, so use a fresh OUT for other
settings.

    uv run python tools/acceptance_optimize.py [--scenarios simple tools/generality/x.toml]
        [--seeds 0 1 2] [--samples 50] [--reference solved]
        [--workers 2 | --scheduler ADDRESS|local:N] [--budget default] [--out acceptance]
        [--physics RANGES]   # the evaluations' second figure, as `rgmcad evaluate --physics`
        [--eval-seed 0] [--layouts layout start]  # the evaluations' seed; which run layouts
        [--set KEY=VALUE ...]     # learning settings of the runs, as `rgmcad optimize --set`

A scenario is a shipped name (scenarios/NAME.toml) or a path to a scenario file.

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


def both(evaluation: dict) -> np.ndarray:
    """rho_g under placement errors and under placement plus physical errors."""
    return np.array([evaluation["rho_g"], evaluation["physics"]["rho_g"]])


WHAT = {"layout": "optimised", "start": "best exploration sample"}


def half_widths(evaluation: dict) -> np.ndarray:
    """The 95 % half-widths of :func:`both`'s two figures."""
    return np.array([np.diff(evaluation["rho_g_interval"])[0],
                     np.diff(evaluation["physics"]["rho_g_interval"])[0]]) / 2.0


def versus(mine: dict, other: dict, name: str) -> str:
    """``mine`` minus ``other`` for both figures, each with the 95 % half-width of the
    difference of two independent evaluations, and whether it is above, level or below."""
    diff = both(mine) - both(other)
    half = np.hypot(half_widths(mine), half_widths(other))
    words = ["above" if d - h > 0 else "below" if d + h < 0 else "level"
             for d, h in zip(diff, half, strict=True)]
    return f"vs {name} " + " / ".join(f"{d:+.3f} +- {h:.3f} ({w})"
                                      for d, h, w in zip(diff, half, words, strict=True))


def fmt(rho: np.ndarray) -> str:
    return f"{rho[0]:.3f} / {rho[1]:.3f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=["simple", "ballrun"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--samples", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="simulate on a Dask cluster (ADDRESS or local:N) instead of --workers")
    parser.add_argument("--budget", default="default")
    parser.add_argument("--reference", default="solved",
                        help="the scenario's named layout to compare with (default: solved)")
    parser.add_argument("--out", default="acceptance")
    parser.add_argument("--physics", default="default",
                        help="the second figure's errors, as `rgmcad evaluate --physics` "
                             "(e.g. position=0.002,heading=1: every part placed by hand too)")
    parser.add_argument("--eval-seed", type=int, default=0,
                        help="seed of every evaluation (another seed: errors independent of "
                             "the default's)")
    parser.add_argument("--layouts", nargs="+", choices=("layout", "start"),
                        default=["layout", "start"],
                        help="which of each run's layouts to evaluate: the optimised one "
                             "(layout) and the best exploration sample (start)")
    parser.add_argument("--set", action="append", default=[], dest="changes",
                        metavar="KEY=VALUE", help="passed to `rgmcad optimize --set` (use a "
                        "fresh --out: runs in OUT are reused whatever their settings)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    common = (["--scheduler", args.scheduler] if args.scheduler
              else ["--workers", str(args.workers)])
    evaluate = ["--rho-g", "--samples", str(args.samples), "--seed", str(args.eval_seed),
                "--physics", args.physics, *common]

    ref = args.reference
    for given in args.scenarios:
        scenario = given if given.endswith(".toml") else f"scenarios/{given}.toml"
        name = Path(scenario).stem
        reference = cached(out / f"eval-{name}-{ref}.json", "evaluate", scenario, "--layout",
                           ref, "--out", str(out / f"{name}-{ref}.png"), *evaluate)
        solved = both(reference)
        rows = []
        for seed in args.seeds:
            run = out / f"{name}-s{seed}"
            summary = cached(out / f"{name}-s{seed}.json", "optimize", scenario, "--run",
                             str(run), "--seed", str(seed), "--budget", args.budget, *common,
                             *(a for pair in args.changes for a in ("--set", pair)))
            evaluations = {lay: cached(out / f"eval-{name}-s{seed}-{lay}.json", "evaluate",
                                       scenario, "--layout", str(run / f"{lay}.json"),
                                       *evaluate) for lay in args.layouts}
            rho = {lay: both(e) for lay, e in evaluations.items()}
            rows.append(rho)
            found = "; ".join(f"{WHAT[lay]} {fmt(rho[lay])} "
                              f"({versus(evaluations[lay], reference, ref)})"
                              for lay in args.layouts)
            print(f"{name} seed {seed}: {summary['simulations']} simulations, "
                  f"{summary['wall_time']:.1f} s, chosen: {summary['source']}; rho_g (placement, "
                  f"+ physics) {found}")
        means = {lay: np.mean([r[lay] for r in rows], axis=0) for lay in args.layouts}
        others = [solved, *(means[lay] for lay in args.layouts if lay != "layout")]
        found = ", ".join(f"{WHAT[lay]} {fmt(means[lay])}" for lay in args.layouts)
        if "layout" in means:
            verdict = "beats" if np.all(means["layout"] >= np.max(others, axis=0)) else \
                "does NOT beat"
            found += f", {ref} {fmt(solved)}: optimised {verdict} the others"
        print(f"{name}: mean rho_g (placement, + physics) {found}\n")


if __name__ == "__main__":
    main()
