"""``rgmcad optimize``: learn the success probability of a scenario's design space and refine
the most robust layout, in a run directory that survives interruptions
(:func:`rgmcad.runs.workflow.optimize_scenario`)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from rgmcad.cli import learning_settings, physics
from rgmcad.cli.common import (
    add_scenario_arg,
    add_scheduler_args,
    budget_name,
    note_first_build,
    parts_dir_arg,
    say,
)
from rgmcad.cli.export import RUN_FILES, export_files
from rgmcad.cli.progress import SimulationBar

__all__ = ["configure", "run"]


def configure(p: argparse.ArgumentParser) -> None:
    add_scenario_arg(p)
    p.add_argument("--run", dest="run_dir", metavar="DIR", help="run directory (default: "
                   "runs/SCENARIO-sSEED, runs/SCENARIO-small-sSEED for --budget small); the "
                   "same command on the same DIR continues an interrupted run")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of every random choice, 0 to 2^32 - 1 (default 0)")
    p.add_argument("--workers", type=int, default=None,
                   help="simulation processes, 1 to 4 per CPU (default: every CPU); results do "
                   "not depend on it")
    p.add_argument("--budget", type=budget_name, default="default", metavar="{default,small}",
                   help="default: the paper's Table 1 settings; small: a quick look")
    p.add_argument("--batch", type=int, metavar="N", help="simulations per exploration batch, "
                   "1 to 10000 (default 10); more keeps more workers busy")
    p.add_argument("--full", action="store_true", help="one success model for the whole "
                   "causal graph instead of one per event (the paper's Fig. 16 comparison)")
    p.add_argument("--start", action="append", default=[], metavar="LAYOUT", help="start from "
                   "your own layout (a named layout of the scenario or a layout file; repeat "
                   "for several): simulated first, and returned unless something more robust "
                   "is found")
    p.add_argument("--centering", choices=("auto", "always", "off"), default=None,
                   help="centre the chosen layout by simulation: auto (default) when the "
                   "exploration found fewer successes than it was to collect, always, or off "
                   "(the paper's pipeline); always/off get their own run directory")
    learning_settings.add_set_arg(p, "the run gets a directory of its own (runs/SCENARIO-KEY=VALUE-sSEED)")
    add_scheduler_args(p)
    physics.add_robustness_arg(p)
    p.add_argument("--json", action="store_true", help="print one JSON summary on stdout")


def run(args) -> int:
    from rgmcad.cli.paths import output_dir
    from rgmcad.runs.checks import MAX_BATCH, MAX_SEED, check_range, check_workers
    from rgmcad.runs.workflow import LAYOUT_FILE, optimize_scenario
    from rgmcad.viewer.report import write_run_report

    check_range(args.seed, 0, MAX_SEED, "--seed", "a seed")
    if args.batch is not None:
        check_range(args.batch, 1, MAX_BATCH, "--batch", "a number of simulations per batch")
    check_workers(args.workers)
    if args.run_dir is not None:  # and again, trying, when the run store opens it
        output_dir(args.run_dir, "--run")
    changes = learning_settings.changes_of(args)
    note_first_build(args)
    bar = SimulationBar(enabled=not args.quiet)
    try:
        done = optimize_scenario(args.scenario, seed=args.seed, budget=args.budget,
                                 run_dir=args.run_dir, workers=args.workers,
                                 build_dir=args.build_dir, progress=bar,
                                 parts_dir=parts_dir_arg(args), scheduler=args.scheduler,
                                 batch=args.batch, full=args.full, starts=args.start,
                                 centering=args.centering, changes=changes,
                                 **physics.robustness_options(args))
    finally:
        bar.close()
    write_run_report(done.run_dir, args.scenario, build_dir=args.build_dir,
                     parts_dir=parts_dir_arg(args))
    if done.finished_before and not args.quiet:
        sys.stderr.write(f"{done.run_dir}: finished already; showing its result\n")
    layout = done.run_dir / LAYOUT_FILE  # where the run is now, not where it was made
    if not all((done.run_dir / name).exists() for name in RUN_FILES):  # the layout as CAD
        try:
            export_files(args, str(layout), None, [done.run_dir / n for n in RUN_FILES])
        except Exception as exc:  # noqa: BLE001 - the run is saved; only the CAD copy is missing
            sys.stderr.write(f"warning: {layout}: not exported as STEP/GLB "
                             f"({type(exc).__name__}: {exc}); try: rgmcad export\n")
    show(done.summary, args.json, done.wall_time if done.finished_before else None)
    if not args.json:
        say(f"next: rgmcad simulate {args.scenario_given} --layout {layout}")
    if not done.verified and not args.quiet:
        sys.stderr.write(
            f"warning: no layout succeeded in the run's {done.summary['simulations']} "
            f"simulations, so {layout} is unchecked: start from a layout of yours that works "
            f"(rgmcad optimize {args.scenario_given} --start LAYOUT), or see where the "
            f"chain stops (rgmcad simulate {args.scenario_given} --layout {layout})\n")
    return 0 if done.verified else 1


def show(summary: dict, as_json: bool, wall_time: float | None = None) -> None:
    """Print a run's summary: one JSON line, or a few lines for people."""
    if as_json:
        out = dict(summary)
        if wall_time is not None:
            out["wall_time_this_call"] = wall_time
        say(json.dumps(out))
        return
    weakest = summary["weakest_event"]
    say(f"{summary['scenario']}: {summary['layout']}")
    if summary.get("hand"):
        from rgmcad.runs.hand_text import hand_headline, weak_link_lines

        say("\n".join([f"built by hand: {hand_headline(summary['hand'])}",
                       *weak_link_lines(summary["hand"], most=3)]))
    say(f"predicted P(success) {summary['probability']:.3f}, weakest link {weakest} "
        f"({summary.get('weakest_probability', summary['event_probabilities'].get(weakest, 1.0)):.3f}"
        f"); {summary['source']}")
    from rgmcad.runs.report import count_line, placement_lines

    for line in [*physics.robustness_lines(summary), count_line(summary),
                 *placement_lines(summary)]:
        say(line)
    run = Path(summary["run"])
    say(f"report: {run / 'report.html'} (as text: {run / 'report.md'}); the layout as CAD: "
        f"{', '.join(str(run / n) for n in RUN_FILES)}")
