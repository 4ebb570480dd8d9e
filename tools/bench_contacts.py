"""What fresh contacts would cost: each shipped scenario's `solved` world stepped as rgmcad
steps it, and with `performCollisionDetection` after every step, so that the contact manifolds
hold the distances of the step's own poses instead of those before it (docs/decisions.md,
"The pose of the step"). Prints CPU microseconds per step, the best of ``--repeat``
alternating rounds of ``--steps`` steps.

    uv run python tools/bench_contacts.py [--steps 1500] [--repeat 2]
"""

import argparse
import time

from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.design_space import values_from_mapping
from rgmcad.scene.loader import load_scenario
from rgmcad.shipped import scenario_path
from rgmcad.sim.cache import PartCache
from rgmcad.sim.engine import Engine, pb
from rgmcad.sim.world import World

SIX = ("simple", "ballrun", "branching", "causality_switch", "long_chain", "teapot")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    engine, cache = Engine(), PartCache()
    for name in SIX:
        scenario = load_scenario(scenario_path(name))
        parts = load_parts(scenario)
        values = values_from_mapping(scenario, scenario.layouts["solved"])
        best = {"as stepped": float("inf"), "fresh contacts": float("inf")}
        for _ in range(args.repeat):
            for mode in best:
                with World(make_scene(scenario, values, parts), scenario.settings, engine,
                           cache) as world:
                    cid, start = world.cid, time.process_time()
                    for _ in range(args.steps):
                        pb.stepSimulation(cid)
                        if mode == "fresh contacts":
                            pb.performCollisionDetection(cid)
                    best[mode] = min(best[mode], time.process_time() - start)
        plain, fresh = (best[m] / args.steps * 1e6 for m in best)
        print(f"{name:18s} as stepped {plain:7.1f} us/step | fresh contacts {fresh:7.1f} us/step"
              f" ({fresh / plain - 1:+.0%})", flush=True)
    engine.close()


if __name__ == "__main__":
    main()
