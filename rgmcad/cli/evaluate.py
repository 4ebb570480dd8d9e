"""``rgmcad evaluate``: a layout's local and global robustness, by simulation
(:func:`rgmcad.runs.evaluation.evaluate_layout`)."""

from __future__ import annotations

import argparse
import json

from rgmcad.cli.common import (
    add_scenario_arg,
    add_scheduler_args,
    note_first_build,
    parts_dir_arg,
    say,
)
from rgmcad.cli.physics import add_physics_arg, physics_arg
from rgmcad.cli.progress import SimulationBar

__all__ = ["configure", "run"]


def configure(p: argparse.ArgumentParser) -> None:
    add_scenario_arg(p)
    p.add_argument("--layout", required=True, help="a named layout of the scenario or a layout "
                   "file (e.g. runs/simple-s0/layout.json)")
    p.add_argument("--samples", type=int, default=50, help="valid layouts simulated per radius, "
                   "1 to 100000 (default 50; 30 radii, so 1500 simulations)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sampling, 0 to 2^32 - 1 "
                   "(default 0)")
    p.add_argument("--workers", type=int, default=None, help="simulation processes, 1 to 4 per "
                   "CPU (default: every CPU); results do not depend on it")
    add_scheduler_args(p)
    add_physics_arg(p)
    p.add_argument("--out", metavar="FILE.png", help="the plot (default: next to a layout file, "
                   "or robustness-SCENARIO-LAYOUT.png here)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def run(args) -> int:
    from rgmcad.cli.paths import output_file
    from rgmcad.runs.checks import MAX_SAMPLES, MAX_SEED, check_range, check_workers, plot_suffixes
    from rgmcad.runs.evaluation import evaluate_layout

    check_range(args.samples, 1, MAX_SAMPLES, "--samples", "a number of layouts per radius")
    check_range(args.seed, 0, MAX_SEED, "--seed", "a seed")
    check_workers(args.workers)
    physics = physics_arg(args)
    if args.out is not None:  # and again, trying, by the workflow, with its default
        output_file(args.out, "--out", plot_suffixes())
    note_first_build(args)
    bar = SimulationBar("validity", count_tested=True, enabled=not args.quiet)
    try:
        result = evaluate_layout(args.scenario, args.layout, samples=args.samples,
                                 seed=args.seed, workers=args.workers,
                                 build_dir=args.build_dir, plot=args.out, progress=bar,
                                 parts_dir=parts_dir_arg(args), scheduler=args.scheduler,
                                 physics=physics)
    finally:
        bar.close()
    if args.json:
        say(json.dumps(result))
        return 0
    low, high = result["rho_g_interval"]
    phys = result["physics"]
    more = "" if phys is None else f" (and {phys['simulations']} with physical errors, below)"
    say(f"{result['scenario']}, layout {result['layout']}: rho_g = {result['rho_g']:.3f} "
        f"[{low:.3f}, {high:.3f}] under placement errors, from {result['simulations']} "
        f"simulations{more} in {result['wall_time']:.0f} s")
    if phys is not None:
        low, high = phys["rho_g_interval"]
        say(f"  rho_g = {phys['rho_g']:.3f} [{low:.3f}, {high:.3f}] under placement plus "
            f"physical errors ({physics.describe()})")
    from rgmcad.runs.robustness import close_in_warning, failures_line

    if warning := close_in_warning(result):
        say(f"warning: {warning}")
    say("eps     rho_l   95 % interval" + ("      + physics" if phys else ""))
    rows = zip(result["curve"], phys["curve"] if phys else [None] * len(result["curve"]),
               strict=True)
    for (e, r, lo, hi), other in list(rows)[::3]:
        more = "" if other is None else f"     {other[1]:5.3f}   [{other[2]:.3f}, {other[3]:.3f}]"
        say(f"{e:5.3f}   {r:5.3f}   [{lo:.3f}, {hi:.3f}]{more}")
    for fig, what in ((result, "placement errors"), (phys, "placement + physical errors")):
        if fig is not None and (line := failures_line(fig["failures"]["close_in"])):
            say(f"{what}, {line}")
    say(f"plot: {result['plot']}")
    return 0
