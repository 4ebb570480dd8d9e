"""``rgmcad evaluate``: how often a layout works when a person builds it, by simulation
(:func:`rgmcad.runs.evaluation.evaluate_layout`); ``--rho-g``: Table 1's local and global
robustness instead."""

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
    p.add_argument("--hand", default="2mm,2deg", help="how far from its printed place a person "
                   "puts each part, e.g. 3mm,1deg (default 2mm,2deg: uniform within +-2 mm "
                   "along x and y and +-2 degrees about the vertical)")
    p.add_argument("--precision", type=float, default=0.05, help="simulate until the 95 %% "
                   "interval of the success rate is this wide on each side, 0.005 to 0.5 "
                   "(default 0.05: +-5 points; at most 320 builds)")
    p.add_argument("--rho-g", action="store_true", help="measure instead the local robustness "
                   "in the normalised design space and its integral rho_g (Table 1)")
    p.add_argument("--samples", type=int, default=None, help="with --rho-g: valid layouts "
                   "simulated per radius, 1 to 100000 (default 50; 30 radii, so 1500 "
                   "simulations)")
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
    from rgmcad.errors import UsageError
    from rgmcad.runs.checks import MAX_SAMPLES, MAX_SEED, check_range, check_workers, plot_suffixes
    from rgmcad.runs.evaluation import evaluate_layout
    from rgmcad.runs.hand import check_precision, parse_hand

    hand = parse_hand(args.hand)
    check_precision(args.precision, "--precision")
    if args.samples is not None and not args.rho_g:
        raise UsageError("--samples", str(args.samples), "counts layouts per radius of --rho-g; "
                         "the hand's figures simulate until --precision is reached")
    args.samples = 50 if args.samples is None else args.samples
    check_range(args.samples, 1, MAX_SAMPLES, "--samples", "a number of layouts per radius")
    check_range(args.seed, 0, MAX_SEED, "--seed", "a seed")
    check_workers(args.workers)
    physics = physics_arg(args)
    if args.out is not None:  # and again, trying, by the workflow, with its default
        output_file(args.out, "--out", plot_suffixes())
    note_first_build(args)
    bar = SimulationBar("validity" if args.rho_g else "hand", count_tested=args.rho_g,
                        enabled=not args.quiet)
    try:
        result = evaluate_layout(args.scenario, args.layout, samples=args.samples,
                                 seed=args.seed, workers=args.workers,
                                 build_dir=args.build_dir, plot=args.out, progress=bar,
                                 parts_dir=parts_dir_arg(args), scheduler=args.scheduler,
                                 physics=physics, measure="rho_g" if args.rho_g else "hand",
                                 hand=hand, precision=args.precision)
    finally:
        bar.close()
    if args.json:
        say(json.dumps(result))
        return 0
    if not args.rho_g:
        from rgmcad.runs.hand_text import hand_headline, hand_table, weak_link_lines

        say(f"{result['scenario']}, layout {result['layout']}: {hand_headline(result)}; "
            f"{result['simulations']} simulations in {result['wall_time']:.0f} s")
        if failed := result["hand"]["failed"]:
            say("  fails first at: " + ", ".join(f"{e} {n}" for e, n in list(failed.items())[:3]))
        say("works, against the hand's error (95 % interval; the same builds at every size):")
        for size, works, builds in hand_table(result):
            say(f"  {size:<22s}{works:>16s}  {builds}")
        for line in weak_link_lines(result):
            say(line)
        say(f"plot: {result['plot']}")
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

