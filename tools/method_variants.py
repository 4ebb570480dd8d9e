"""Our method under other learning settings, scored like the benchmark scores it.

Runs ``T`` trials of ``rgmcad optimize`` with the default budget changed by ``--set
NAME=VALUE`` (any :class:`~rgmcad.learning.settings.LearningSettings` field) and evaluates
each returned layout with the benchmark's protocol and seeds, so two variants' rho_g pair up
trial by trial (common random numbers). Everything is journaled under ``--out``: run it
again to continue.

    uv run python tools/method_variants.py scenarios/ballrun.toml --out /tmp/r0 \\
        --set error_radius=0 --set placement_samples=32
    uv run python tools/method_variants.py scenarios/ballrun.toml --out /tmp/r1
"""

from __future__ import annotations

import argparse
import ast

from rgmcad.learning.settings import budget
from rgmcad.runs.benchmark import run_benchmark


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario")
    p.add_argument("--out", required=True)
    p.add_argument("--trials", type=int, default=3)
    p.add_argument("--samples", type=int, default=20)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--physics", action="store_true", help="also under physical errors")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    args = p.parse_args()
    changes = {k: ast.literal_eval(v) for k, v in (s.split("=", 1) for s in args.set)}
    settings = budget("default").replace(**changes)
    from rgmcad.scene.perturbation import DEFAULT_PHYSICS

    table = run_benchmark(args.scenario, args.out, methods=("ours",), trials=args.trials,
                          samples=args.samples, ours_settings=settings, workers=args.workers,
                          physics=DEFAULT_PHYSICS if args.physics else None)
    row = table["rows"][0]
    print(f"{changes or 'defaults'}: rho_g per trial "
          + " ".join(f"{v:.3f}" for v in row["rho_g"]) + f", mean {row['rho_g_mean']:.3f}, "
          f"simulations {row['simulations_mean']:.0f}")


if __name__ == "__main__":
    main()
