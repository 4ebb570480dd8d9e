"""Where a simulation's time goes, per shipped scenario: stepping vs everything else.

Prints, for each scenario's `solved` layout and its first valid Sobol layouts (the mix of
successes and failures an optimisation run simulates), the mean wall time per
simulation, the time inside pybullet's stepSimulation, the overhead (world build, validity,
event checks, bookkeeping) as a share of the stepping time, and simulations per second on one
core. Simulations share one engine (without pybullet's renderer) and one part cache, as in a
worker process; the stepping time (the physics floor) is that of as many raw steps of the same
world. The same two figures are also given in CPU time (`time.process_time`), which other
processes on a shared machine do not inflate. Also times the validity test on a 50-body
scene, and what a simulation given no engine pays for its own (connecting and disconnecting a
pybullet client).

    uv run python tools/bench_simulation.py [--repeat 5] [--scenarios long_chain,teapot]
"""

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.stats import qmc

from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.design_space import values_from_mapping, values_from_vector
from rgmcad.scene.loader import load_scenario, parse_scenario
from rgmcad.sim.cache import PartCache
from rgmcad.sim.engine import Engine, pb
from rgmcad.sim.run import simulate
from rgmcad.sim.validity import check_validity
from rgmcad.sim.world import World


def bench_scenario(path: Path, repeat: int, args_valid: int, engine: Engine) -> None:
    scenario = load_scenario(path)
    parts = load_parts(scenario)
    cache = PartCache()
    # the solved layout plus the first valid layouts of a Sobol sequence: the mix of
    # successes and failures an optimisation run simulates
    layouts = [values_from_mapping(scenario, scenario.layouts["solved"])]
    for v in qmc.Sobol(scenario.dimension, seed=0).random(256):
        values = values_from_vector(scenario, v)
        if check_validity(make_scene(scenario, values, parts), cache=cache).valid:
            layouts.append(values)
        if len(layouts) == 1 + args_valid:
            break
    simulate(scenario, layouts[0], parts, engine=engine, cache=cache)  # warm the cache
    wall = step = valid = build = cpu = cpu_step = 0.0
    n = sim = 0
    for _ in range(repeat):
        for values in layouts:
            start = time.process_time()
            r = simulate(scenario, values, parts, engine=engine, cache=cache)
            if r.outcome.value == "invalid":
                continue
            cpu += time.process_time() - start
            wall += r.wall_time
            seconds, cpu_seconds = _stepping(scenario, values, parts, r.steps, engine, cache)
            step += seconds
            cpu_step += cpu_seconds
            valid += r.validity_time
            build += r.build_time
            sim += r.sim_time
            n += 1
    overhead = wall - step
    per_step = wall - step - valid - build  # event checks and bookkeeping, during the run
    print(f"{scenario.name:18s} {n:3d} runs {wall / n * 1e3:7.1f} ms/sim | step "
          f"{step / n * 1e3:7.1f} | validity {valid / n * 1e3:5.1f} | build {build / n * 1e3:5.1f}"
          f" | events+loop {per_step / n * 1e3:6.1f} ms ({per_step / step * 100:4.0f} %) | all "
          f"but stepping {overhead / step * 100:5.1f} % | {n / wall:5.1f} sim/s "
          f"{sim / wall:5.1f}x real time | CPU {cpu / n * 1e3:7.1f} ms/sim, stepping "
          f"{cpu_step / n * 1e3:7.1f}", flush=True)


def _stepping(scenario, values, parts, steps: int, engine: Engine,
              cache: PartCache) -> tuple[float, float]:
    """Wall and CPU seconds of the simulation's physics steps alone: as many raw steps of the
    same world (the simulation itself reads no clock per step)."""
    with World(make_scene(scenario, values, parts), scenario.settings, engine, cache) as world:
        step, cid = pb.stepSimulation, world.cid
        start, cpu = time.perf_counter(), time.process_time()
        for _ in range(steps):
            step(cid)
        return time.perf_counter() - start, time.process_time() - cpu


def bench_validity() -> None:
    cube = {"part": "box", "params": {"length": 0.02, "width": 0.02, "height": 0.02}}
    objects = {f"c{i}": {**cube, "pose": {"x": 0.03 * (i % 10), "y": 0.03 * (i // 10),
                                          "z": 0.01, "heading": 3 * i}} for i in range(50)}
    scenario = parse_scenario({"objects": objects, "events": {
        "e": {"type": "contact", "first": "c0", "second": "c1"}}})
    scene = make_scene(scenario, np.zeros(0), load_parts(scenario))
    cache = PartCache()
    check_validity(scene, cache=cache)
    start = time.perf_counter()
    for _ in range(20):
        check_validity(scene, cache=cache)
    print(f"validity, 50 bodies: {(time.perf_counter() - start) / 20 * 1e3:.2f} ms per test")


def bench_engine(n: int = 50) -> None:
    start = time.perf_counter()
    for _ in range(n):
        Engine().close()
    print(f"an engine of its own (connect + disconnect): {(time.perf_counter() - start) / n * 1e3:.1f}"
          " ms per simulation")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--layouts", type=int, default=8, help="valid Sobol layouts per scenario")
    parser.add_argument("--scenarios", default="", help="comma-separated names (default: all)")
    args = parser.parse_args()
    only = set(filter(None, args.scenarios.split(",")))
    with Engine(renderer=False) as engine:
        for path in sorted(Path("scenarios").glob("*.toml")):
            if not only or path.stem in only:
                bench_scenario(path, args.repeat, args.layouts, engine)
    bench_validity()
    bench_engine()


if __name__ == "__main__":
    main()
