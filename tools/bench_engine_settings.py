"""Engine settings that could make large domino scenes cheaper, measured against the outcomes.

For each scenario: its ``solved`` layout and ``--layouts`` uniform random valid layouts
(seeded), simulated with today's settings and with each variant, alternating layout by layout
in one process. Prints the CPU time per simulation of each variant relative to today's and
how many simulations changed outcome or event times. Variants (applied after the world is
built, so nothing else changes):

* ``sleep``: Bullet's deactivation of resting bodies (its default thresholds: 0.8 m/s,
  1 rad/s, 2 s); rgmcad disables it so that slow levers are never frozen;
* ``residual``: the solver stops iterating once the largest impulse change is under 1e-4
  (pybullet's default 1e-7);
* ``no_ccd``: no continuous collision detection.

    uv run python tools/bench_engine_settings.py [--scenarios causality_switch simple]
"""

import argparse
import time
from pathlib import Path

import numpy as np

from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.design_space import values_from_mapping, values_from_vector
from rgmcad.scene.loader import load_scenario
from rgmcad.sim import world as world_module
from rgmcad.sim.cache import PartCache
from rgmcad.sim.engine import Engine, pb
from rgmcad.sim.run import simulate
from rgmcad.sim.validity import check_validity


def _bodies(world):
    return sorted({h.uid for h in world.handles.values()})


def sleep(world):
    for uid in _bodies(world):
        for link in range(-1, pb.getNumJoints(uid, physicsClientId=world.cid)):
            pb.changeDynamics(uid, link, activationState=pb.ACTIVATION_STATE_ENABLE_SLEEPING,
                              physicsClientId=world.cid)


def residual(world):
    pb.setPhysicsEngineParameter(solverResidualThreshold=1e-4, physicsClientId=world.cid)


def no_ccd(world):
    for uid in _bodies(world):
        pb.changeDynamics(uid, -1, ccdSweptSphereRadius=0, physicsClientId=world.cid)


def _each_link(world, **dynamics):
    for uid in _bodies(world):
        for link in range(-1, pb.getNumJoints(uid, physicsClientId=world.cid)):
            pb.changeDynamics(uid, link, **dynamics, physicsClientId=world.cid)


def sleep_slow(world):
    """Sleeping only for bodies slower than 1 cm/s and 0.01 rad/s for 2 s."""
    _each_link(world, activationState=pb.ACTIVATION_STATE_ENABLE_SLEEPING, sleepThreshold=0.01)


def no_speculative(world):
    """Contact points farther apart than 0 m are not handed to the solver."""
    _each_link(world, contactProcessingThreshold=0.0)


def split(world):
    pb.setPhysicsEngineParameter(useSplitImpulse=1, physicsClientId=world.cid)


def islands(world):
    """Islands solved one by one (no batching of small islands)."""
    pb.setPhysicsEngineParameter(minimumSolverIslandSize=1, physicsClientId=world.cid)


VARIANTS = {"today": None, "sleep": sleep, "sleep_slow": sleep_slow, "residual": residual,
            "no_ccd": no_ccd, "no_speculative": no_speculative, "split": split,
            "islands": islands}


class _Patched(world_module.World):
    variant = None

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if _Patched.variant is not None:
            _Patched.variant(self)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--scenarios", nargs="*", default=["causality_switch", "simple"])
    parser.add_argument("--layouts", type=int, default=20)
    parser.add_argument("--seed", type=int, default=15)
    parser.add_argument("--variants", nargs="*", default=list(VARIANTS))
    args = parser.parse_args()
    variants = {v: VARIANTS[v] for v in ["today", *args.variants] if v in VARIANTS}
    import rgmcad.sim.run as run_module

    run_module.World = _Patched
    engine, cache = Engine(renderer=False), PartCache()
    for name in args.scenarios:
        scenario = load_scenario(Path("scenarios") / f"{name}.toml")
        parts = load_parts(scenario)
        layouts = [values_from_mapping(scenario, scenario.layouts["solved"])]
        rng = np.random.default_rng(args.seed)
        while len(layouts) < 1 + args.layouts:
            values = values_from_vector(scenario, rng.random(scenario.dimension))
            if check_validity(make_scene(scenario, values, parts), cache=cache).valid:
                layouts.append(values)
        cpu = dict.fromkeys(variants, 0.0)
        moved = dict.fromkeys(variants, 0)
        outcome_moved = dict.fromkeys(variants, 0)
        solved = {}
        for k, values in enumerate(layouts):
            results = {}
            for v, fn in variants.items():
                _Patched.variant = fn
                start = time.process_time()
                results[v] = simulate(scenario, values, parts, check=False, engine=engine,
                                      cache=cache)
                cpu[v] += time.process_time() - start
                if k == 0:
                    solved[v] = results[v].outcome.value
            for v, r in results.items():
                moved[v] += r.events != results["today"].events
                outcome_moved[v] += r.outcome != results["today"].outcome
        n = len(layouts)
        for v in variants:
            print(f"{name:17s} {v:9s} {cpu[v] / n * 1e3:7.1f} ms/sim ({cpu[v] / cpu['today']:.2f}x)"
                  f" | events moved {moved[v]}/{n}, outcome moved {outcome_moved[v]}/{n}"
                  f" | solved: {solved[v]}", flush=True)


if __name__ == "__main__":
    main()
