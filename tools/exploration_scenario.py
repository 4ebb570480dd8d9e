"""How fast the exploration alone finds a scenario's successes, for values of one setting.

For each value and seed: the samples simulated until N+ global successes (or the cap), the
sample of the first success, the most events any sample reached, and the wall time. The
exploration is the one `rgmcad optimize` runs first (same settings, no start layout), with
its own seed, without the learning that follows it.

    uv run python tools/exploration_scenario.py tools/generality/domino_arc.toml \
        --setting exploration_staged --values 0 1 --seeds 0 1 2 3 --workers 2
"""

import argparse
import time

import numpy as np

from rgmcad.learning.sampling import explore
from rgmcad.learning.settings import LearningSettings
from rgmcad.runs.executor import make_executor
from rgmcad.runs.problem import ScenarioProblem, simulate_layout_task


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("--setting", default="exploration_staged")
    ap.add_argument("--values", type=float, nargs="+", default=[0.0, 1.0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args()
    problem = ScenarioProblem(args.scenario)
    base = LearningSettings()
    kind = type(getattr(base, args.setting))
    executor = make_executor(args.workers, problem.context)

    def simulate(X):
        return [r.label() for r in executor.map_context(simulate_layout_task, [(x, True) for x in X])]

    print(f"{args.scenario}: d = {problem.dimension}, {len(problem.event_parents)} events, "
          f"N+ = {base.n_successes}")
    print(f"| {args.setting} | seed | samples | N+ reached | first success at | most events | s |")
    print("|---|---|---|---|---|---|---|")
    try:
        for value in args.values:
            settings = base.replace(**{args.setting: kind(value)})
            for seed in args.seeds:
                start = time.perf_counter()
                found = explore(problem, settings, np.random.default_rng(seed), simulate=simulate)
                first = next((i for i, lab in enumerate(found.labels) if lab.success), None)
                print(f"| {value:g} | {seed} | {len(found.X):,} | "
                      f"{'yes' if found.n_global_successes >= settings.n_successes else 'no'}"
                      f" ({found.n_global_successes}) | {'-' if first is None else f'{first:,}'} | "
                      f"{max(lab.n_success for lab in found.labels)} | "
                      f"{time.perf_counter() - start:.0f} |", flush=True)
    finally:
        executor.close()


if __name__ == "__main__":
    main()
