"""Every tolerance a run printed, placed at its printed bound and simulated, as a maker (or a
reviewer) would: the run's layout with one parameter moved by the number printed (to 0.1 mm
or 0.1 degree), set as a real value, the validity test included. A side printed "push
against the X" is placed at its bound (the parts just clear).

    uv run python tools/check_printed.py SCENARIO RUN_DIR [SCENARIO RUN_DIR ...]

Prints, per run, the sides checked and those holding, and each side that does not.
"""

import json
import sys
from pathlib import Path

import numpy as np

from rgmcad.runs.problem import ScenarioContext
from rgmcad.runs.report import side_texts, user_scale
from rgmcad.sim.run import Outcome, simulate


def check(scenario_path: str, run_dir: str) -> tuple[int, int, list[str]]:
    summary = json.loads((Path(run_dir) / "result.json").read_text())
    context = ScenarioContext.load(scenario_path)
    values = np.array([summary["values"][f.name] for f in context.scenario.free])
    checked, held, bad = 0, 0, []
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
                checked += 1
                if result.outcome is Outcome.SUCCESS:
                    held += 1
                else:
                    bad.append(f"{f.name} {text} -> {result.outcome.value}")
    finally:
        context.close()
    return checked, held, bad


def main(argv: list[str]) -> int:
    if len(argv) % 2:
        print(__doc__, file=sys.stderr)
        return 2
    total = [0, 0]
    for scenario, run in zip(argv[::2], argv[1::2], strict=True):
        checked, held, bad = check(scenario, run)
        total[0] += checked
        total[1] += held
        print(f"{scenario} {run}: {held} of {checked} printed sides hold"
              + "".join(f"\n  {b}" for b in bad))
    print(f"all: {total[1]} of {total[0]} printed sides hold")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
