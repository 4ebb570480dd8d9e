"""Our method learning in K fixed physical worlds: every learning simulation run once in each
of K per-body draws of the physical ranges and labelled a success only where all succeed.

``rgmcad optimize --physics-corners`` learns in two worlds where every body sits at the same
end of every range; those cannot see what depends on one body against another (ballrun's
layouts fail on relative masses). Here the worlds are ordinary per-body draws of
``--physics`` (draw numbers from 2^40 on, which no evaluation uses, under the run's seed),
so such a dependence shows. Prints the run's folder; evaluate it with ``rgmcad evaluate
SCENARIO --layout DIR/layout.json``. A run continues from its journal when run again; the
worlds are not part of the run's identity, so give other ``--worlds`` or ``--physics`` a
``--run`` of their own.

    uv run python tools/learning_worlds.py scenarios/ballrun.toml --seed 0 --worlds 2 \\
        --run /tmp/bw0
"""

from __future__ import annotations

import argparse

from rgmcad.runs.store import RecordedProblem
from rgmcad.runs.workflow import optimize_scenario
from rgmcad.scene.perturbation import PhysicsDraw, parse_physics_ranges

FIRST_DRAW = 1 << 40


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario")
    p.add_argument("--run", required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--worlds", type=int, default=2, help="K, the number of fixed draws")
    p.add_argument("--physics", default="default", help="ranges, as `evaluate --physics`")
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args()
    ranges = parse_physics_ranges(args.physics)
    worlds = tuple(PhysicsDraw(ranges, args.seed, FIRST_DRAW + i) for i in range(args.worlds))

    class InWorlds(RecordedProblem):
        def __init__(self, *a, **kw):
            super().__init__(*a, **kw)
            self.physics_worlds = worlds

    run = optimize_scenario(args.scenario, seed=args.seed, run_dir=args.run,
                            workers=args.workers, recorded=InWorlds)
    print(run.run_dir)


if __name__ == "__main__":
    main()
