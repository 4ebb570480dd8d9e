"""How fast the exploration chains events, on synthetic causal chains (no simulator).

Each chain has d parameters and d / 2 events in a row; event k succeeds when its own two
coordinates (2k, 2k + 1) fall in a box of side WIDTH placed at random, and only after event
k - 1 succeeded. That is the structure a real machine's parameters mostly have (each event
depends on the parts it moves), stripped of everything else. For each setting value the
table gives, per seed, the samples the exploration simulated until N+ successes, or
`capped(k)` when it hit its iteration cap with k events reached at best.

    uv run python tools/exploration_chains.py [--d 18] [--width 0.5] [--seeds 8]
        [--setting exploration_move_share] [--values 1 0.4]

About 15 s per value for 12 seeds at d = 18 (the exploration at the default
budget, its SVM-free part only).
"""

import argparse
import time

import numpy as np

from rgmcad.learning import LearningSettings
from rgmcad.learning.oracles import chain_oracle
from rgmcad.learning.sampling import explore


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--d", type=int, default=18)
    ap.add_argument("--width", type=float, default=0.5)
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--setting", default="exploration_move_share")
    ap.add_argument("--values", type=float, nargs="+", default=[1.0, 0.4])
    args = ap.parse_args()
    base = LearningSettings()
    kind = type(getattr(base, args.setting))
    print(f"d = {args.d}, {args.d // 2} events, box side {args.width}, N+ = {base.n_successes}")
    print(f"| {args.setting} | reached N+ | mean samples when reached | per seed |")
    print("|---|---|---|---|")
    for value in args.values:
        settings = base.replace(**{args.setting: kind(value)})
        cells, reached = [], []
        start = time.perf_counter()
        for seed in range(args.seeds):
            found = explore(chain_oracle(args.d, args.width, seed), settings,
                            np.random.default_rng(seed))
            if found.n_global_successes >= settings.n_successes:
                reached.append(len(found.X))
                cells.append(str(len(found.X)))
            else:
                cells.append(f"capped({max(lab.n_success for lab in found.labels)})")
        mean = f"{np.mean(reached):,.0f}" if reached else "-"
        print(f"| {value:g} | {len(reached)}/{args.seeds} | {mean} | {' '.join(cells)} |"
              f"  ({time.perf_counter() - start:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
