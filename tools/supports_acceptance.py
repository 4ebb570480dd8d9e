"""Acceptance figures of the supports (issue 51) on the six shipped scenarios' optimised
layouts: raised static parts, stands, parts left without one, and the runs in which a moving
body touched a stand or whose outcome changed with the stands simulated.

The stands are designed from the nominal run and RUNS perturbed runs (a hand's 2 mm / 2°
errors plus physical errors, draws 0..RUNS-1 of seed DESIGN_SEED), then checked on the
nominal run and RUNS other perturbed runs (seed CHECK_SEED), each simulated without and with
the stands. A layout is a run's layout.json (default: runs/hand-acceptance/NAME-default-s0,
git-ignored: made by tools/hand_acceptance.py), else the scenario's `solved` layout.

    uv run python tools/supports_acceptance.py [--scenarios simple ballrun ...] [--runs 50]
        [--design-seed 0] [--check-seed 1] [--layout-dir runs/hand-acceptance] [--controls]

--controls also simulates the check runs three times more with no stand in reach, to tell what
changes an outcome: with the stands 100 m below the layout (the same bodies, no pair with a
moving body), and with no stands but the layout's first value 1 nm and 1 um off (changes nothing
physical can tell from none): the runs whose outcome differs from the run without stands.
"""

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from rgmcad.making.clearance import ClearanceSettings, check_stands, draws, plan_supports
from rgmcad.scene.bodies import load_parts
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.loader import load_scenario

SIX = ("simple", "ballrun", "branching", "causality_switch", "long_chain", "teapot")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", nargs="+", default=list(SIX))
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--design-seed", type=int, default=0)
    ap.add_argument("--check-seed", type=int, default=1)
    ap.add_argument("--layout-dir", default="runs/hand-acceptance")
    ap.add_argument("--controls", action="store_true")
    args = ap.parse_args()
    for name in args.scenarios:
        scenario = load_scenario(f"scenarios/{name}.toml")
        parts = load_parts(scenario)
        layout = Path(args.layout_dir) / f"{name}-default-s0" / "layout.json"
        label, values = resolve_layout(scenario, str(layout) if layout.exists() else "solved",
                                       None)
        start = time.perf_counter()
        plan = plan_supports(scenario, values, parts,
                             ClearanceSettings(runs=args.runs, seed=args.design_seed))
        designed = time.perf_counter() - start
        check = ClearanceSettings(runs=args.runs, seed=args.check_seed)
        checks, _ = check_stands(scenario, values, parts, plan.stands, draws(check))
        checked = time.perf_counter() - start - designed
        print(f"{name} ({label}): {plan.summary()}; design {designed:.0f} s, "
              f"{plan.rounds} round(s)")
        touched = [c for c in checks if c.touches]
        changed = [c for c in checks if not c.same]
        quiet = [c for c in changed if not c.touches]
        print(f"  check, seed {args.check_seed}: {len(checks)} runs, {len(touched)} with a "
              f"stand touched, {len(changed)} with another outcome ({len(quiet)} of them "
              f"with no stand touched); {checked:.0f} s")
        for stand in plan.stands:
            print(f"  {stand.describe()}")
        for part, why in plan.unsupported:
            print(f"  {part}: {why}")
        for c in touched[:5]:
            print(f"  touched in draw {c.draw}: {c.touches[:3]}")
        for c in changed[:5]:
            print(f"  changed in draw {c.draw}: {c.without[0]} -> {c.with_stands[0]}")
        if args.controls:
            _controls(scenario, values, parts, plan.stands, checks, check)


def _controls(scenario, values, parts, stands, checks, check) -> None:
    """The check runs with the stands far away, and with a 1 nm nudge and no stands."""
    without = [c.without for c in checks]
    away = np.eye(4)
    away[2, 3] = -100.0
    far, _ = check_stands(scenario, values, parts, [s.moved(away) for s in stands],
                          draws(check), baseline=without)
    rows = [("no stands", [dataclasses.replace(c, with_stands=c.without) for c in checks]),
            ("stands", checks), ("stands 100 m away", far)]
    for label, off in (("layout 1 nm off", 1e-9), ("layout 1 um off", 1e-6)):
        nudged = np.array(values, float)
        nudged[0] += off
        rows.append((label, check_stands(scenario, nudged, parts, (), draws(check),
                                         baseline=without)[0]))
    n = len(checks)
    print("  controls (successes / runs whose outcome differs from no stands): " + "; ".join(
        f"{label} {sum(c.with_stands[0] == 'success' for c in runs)}/{n} "
        f"{sum(not c.same for c in runs)}" for label, runs in rows))


if __name__ == "__main__":
    main()
