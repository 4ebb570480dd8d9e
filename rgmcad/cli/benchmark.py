"""``rgmcad benchmark``: our method against the paper's baselines and CMA-ES on one scenario,
a table like the paper's Table 1 and a figure like its Fig. 15
(:func:`rgmcad.runs.benchmark.run_benchmark`); resumable."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from rgmcad.cli.common import (
    add_scenario_arg,
    add_scheduler_args,
    budget_name,
    parts_dir_arg,
    say,
)
from rgmcad.cli.learning_settings import add_set_arg, setting_changes
from rgmcad.cli.physics import add_physics_arg, physics_arg

__all__ = ["configure", "run"]

def _methods(text: str) -> tuple[str, ...]:
    from rgmcad.runs.benchmark import METHODS

    names = tuple(w.strip().lower() for w in text.split(",") if w.strip())
    bad = [n for n in names if n not in METHODS]
    if bad or not names or len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(f"{text!r}: expected distinct names among "
                                         f"{','.join(METHODS)}")
    return names




def configure(p: argparse.ArgumentParser) -> None:
    add_scenario_arg(p)
    p.add_argument("--out", metavar="DIR", help="where the runs, the table and the figure go "
                   "(default: benchmarks/SCENARIO); the same command on the same DIR continues "
                   "an interrupted benchmark")
    p.add_argument("--methods", type=_methods, default=None, metavar="M1,M2",
                   help="among ours,full,b1,b2,b3,cma (default: ours,b1,b2,b3,cma; full: "
                   "ours with one global model, the paper's Fig. 16); rows other calls "
                   "finished in --out under the same protocol stay in the table")
    p.add_argument("--trials", type=int, default=10, help="runs of each method, seeds SEED.."
                   "SEED+T-1 (default 10, as the paper)")
    p.add_argument("--seed", type=int, default=0, help="base seed (default 0)")
    p.add_argument("--budget-sims", type=int, default=None, metavar="B",
                   help="simulations per baseline run (default: the mean our method used, "
                   "in this call or in --out's finished trials)")
    p.add_argument("--samples", type=int, default=50, help="valid layouts per radius in the "
                   "evaluation of each layout (default 50; 30 radii)")
    p.add_argument("--ours-budget", type=budget_name, default="default",
                   metavar="{default,small}", help="settings of our method (default: the "
                   "paper's Table 1 settings)")
    add_set_arg(p, "ours' settings only (give the benchmark another --out)")
    p.add_argument("--workers", type=int, default=None, help="simulation processes, 1 to 4 per "
                   "CPU (default: every CPU); results do not depend on it")
    p.add_argument("--reference", action="append", default=[], metavar="LAYOUT",
                   help="a layout of yours to compare with (a named layout of the scenario, "
                   "e.g. solved, or a layout file): a row of the table, evaluated under every "
                   "trial's errors, with its paired difference to ours; repeatable")
    add_physics_arg(p)
    p.add_argument("--json", action="store_true", help="print the table as one JSON object")
    add_scheduler_args(p)


class _Stages:
    """One stderr line per stage (method and trial)."""

    def stage(self, name: str, total: int | None = None) -> None:
        if " t" in name:
            sys.stderr.write(f"{name}\n")

    def simulated(self, record, replayed: bool = False) -> None:
        pass

    def tested(self, n: int) -> None:
        pass


def run(args) -> int:
    from rgmcad.cli.paths import output_dir
    from rgmcad.learning.settings import budget
    from rgmcad.runs.benchmark import DEFAULT_METHODS, TABLE_MD, run_benchmark
    from rgmcad.runs.checks import check_workers
    from rgmcad.scene.loader import load_scenario

    check_workers(args.workers)
    changes = setting_changes(args.changes, args.ours_budget)
    physics = physics_arg(args)
    parts_dir = parts_dir_arg(args)
    scenario = load_scenario(args.scenario, parts_dir=parts_dir)  # refused before any folder
    out = args.out if args.out is not None else str(Path("benchmarks") / scenario.name)
    output_dir(out, "--out")
    table = run_benchmark(args.scenario, out, methods=args.methods or DEFAULT_METHODS,
                          trials=args.trials, seed=args.seed, budget_sims=args.budget_sims,
                          samples=args.samples, ours_budget=args.ours_budget,
                          ours_settings=budget(args.ours_budget).replace(**changes) if changes
                          else None,
                          workers=args.workers, build_dir=args.build_dir, progress=_Stages(),
                          scheduler=args.scheduler, parts_dir=parts_dir, physics=physics,
                          references=args.reference)
    if args.json:
        say(json.dumps(table))
        return 0
    say((Path(out) / TABLE_MD).read_text().rstrip())
    say(f"table and figure in {out}")
    return 0
