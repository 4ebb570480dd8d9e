"""Every tolerance a run printed, placed at its printed bound and simulated, as a maker (or a
reviewer) would: the run's layout with one parameter moved by the number printed (to 0.1 mm
or 0.1 degree), set as a real value, the validity test included. A side printed "push
against the X" is placed at its bound (the parts just clear).

    uv run python tools/check_printed.py [--hand N] SCENARIO RUN_DIR [SCENARIO RUN_DIR ...]

Prints, per run, the sides checked and those holding, and each side that does not. With
``--hand N``: each numeric side also placed at its bound with every other part placed by the
run's hand (its summary's hand and physical errors), on N builds the run never simulated
(draws 1000 onwards): a side holds where it works at a rate the page states (its 95 %
interval reaches the headline's); and how many of the same builds it lost against the layout.
"""

import json
import sys
from pathlib import Path

import numpy as np

from rgmcad.runs.executor import make_executor
from rgmcad.runs.hand import Builds, Hand, rate_text
from rgmcad.runs.problem import ScenarioContext, ScenarioProblem
from rgmcad.runs.report import side_texts, user_scale
from rgmcad.runs.robustness import wilson_interval
from rgmcad.scene.design_space import vector_from_values
from rgmcad.scene.perturbation import PhysicsDraw, PhysicsRanges
from rgmcad.sim.run import Outcome, simulate

FRESH = 1000  # the first draw index of the new builds: beyond any run's


def head_of(run: str) -> tuple[float, float, float]:
    h = json.loads((Path(run) / "result.json").read_text())["hand"]["hand"]
    return h["rate"], *h["interval"]


def by_hand(scenario_path: str, summary: dict, sides: list, n: int):
    """Sides ``[(real values, label)]`` under the run's hand on ``n`` new builds: how many
    work at a rate the page states (the bound's 95 % interval reaches the headline's), each
    side's loss against the layout on the same builds (builds), and a line per side."""
    head = summary["hand"]["hand"]
    hand = Hand(head["position_mm"], head["heading_deg"])
    physics = None if head["physics"] is None else PhysicsRanges(**head["physics"])
    draws = [PhysicsDraw(hand.ranges(physics), summary["seed"], FRESH + i) for i in range(n)]
    stated_low = head["interval"][0]
    problem = ScenarioProblem(scenario_path)
    executor = make_executor(None, problem.context)
    held, losses, lines = 0, [], []
    try:
        builds = Builds(executor)

        def works(values):
            x = vector_from_values(problem.scenario, values)
            return sum(r.outcome is Outcome.SUCCESS for r in builds(x, draws))

        base = works(np.array(list(summary["values"].values())))
        for values, label in sides:
            at = works(values)
            low, high = wilson_interval(at, n)
            held += high >= stated_low
            losses.append(base - at)
            lines.append(f"{label}: {rate_text(at / n, low, high)} ({at} of {n}; the layout "
                         f"{base}){'' if high >= stated_low else ' BELOW the page'}")
    finally:
        executor.close()
    return held, losses, lines


def check(scenario_path: str, run_dir: str, hand: int = 0):
    summary = json.loads((Path(run_dir) / "result.json").read_text())
    context = ScenarioContext.load(scenario_path)
    values = np.array([summary["values"][f.name] for f in context.scenario.free])
    checked, held, bad, numeric = 0, 0, [], []
    try:
        for j, f in enumerate(context.scenario.free):
            k, unit = user_scale(f)
            for side, text, sign in zip(("low", "high"), side_texts(summary, f.name, k), (-1, 1),
                                        strict=True):
                if text.startswith("push"):
                    moved = summary["tolerances"][f.name][side == "high"]
                else:
                    moved = float(text.split()[0].lstrip("+-")) / k
                if moved == 0.0:
                    continue
                v = values.copy()
                v[j] = values[j] + sign * moved
                result = simulate(context.scenario, v, context.parts, cache=context.cache)
                if not text.startswith("push"):
                    numeric.append((v, f"{f.name} {text}"))
                checked += 1
                if result.outcome is Outcome.SUCCESS:
                    held += 1
                else:
                    bad.append(f"{f.name} {text} -> {result.outcome.value}")
    finally:
        context.close()
    if not hand:
        return checked, held, bad, None
    return checked, held, bad, (len(numeric), *by_hand(scenario_path, summary, numeric, hand))


def main(argv: list[str]) -> int:
    hand = 0
    if argv[:1] == ["--hand"] and len(argv) > 1:
        hand, argv = int(argv[1]), argv[2:]
    if len(argv) % 2 or not argv:
        print(__doc__, file=sys.stderr)
        return 2
    total, total_losses = [0, 0, 0, 0], []
    for scenario, run in zip(argv[::2], argv[1::2], strict=True):
        checked, held, bad, under_hand = check(scenario, run, hand)
        total[0] += checked
        total[1] += held
        print(f"{scenario} {run}: {held} of {checked} printed sides hold"
              + "".join(f"\n  {b}" for b in bad))
        if under_hand is not None:
            sides, ok, losses, lines = under_hand
            total[2] += sides
            total[3] += ok
            total_losses.extend(losses)
            print(f"  built by hand ({hand} new builds), at a rate the page states "
                  f"({rate_text(*head_of(run))}): {ok} of {sides} numeric sides"
                  + "".join(f"\n    {b}" for b in lines))
    print(f"all: {total[1]} of {total[0]} printed sides hold"
          + (f"; built by hand, {total[3]} of {total[2]} at a rate the page states; lost "
             f"against the layout on the same builds: mean {np.mean(total_losses):.1f}, most "
             f"{max(total_losses)} of {hand}" if hand and total_losses else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
