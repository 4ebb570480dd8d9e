"""A scenario's ``[simulation]`` settings against variants of them: cost and outcomes.

Simulates the scenario's ``solved`` layout and ``--layouts`` uniform random valid layouts
(seeded) with the scenario's own settings and with each variant, alternating layout by layout in
one process (one engine, one part cache, as in a worker). Prints per variant the CPU time per
simulation relative to the scenario's settings, the successes, how many layouts changed event
times or outcome (and which outcomes moved), and the ``solved`` layout's outcome.

    uv run python tools/compare_settings.py scenarios/teapot.toml --layouts 40 \\
        --variant residual:solver_residual_threshold=1e-4 \\
        --variant both:solver_residual_threshold=1e-4,speculative_contacts=false [--near 0.05]
"""

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.design_space import (
    values_from_mapping,
    values_from_vector,
    vector_from_values,
)
from rgmcad.scene.loader import load_scenario
from rgmcad.sim.cache import PartCache
from rgmcad.sim.engine import Engine
from rgmcad.sim.run import simulate
from rgmcad.sim.validity import check_validity


def parse_variant(text: str, base) -> tuple[str, object]:
    name, _, assignments = text.partition(":")
    changes = {}
    for item in filter(None, assignments.split(",")):
        key, _, value = item.partition("=")
        current = getattr(base, key)
        if isinstance(current, bool):
            changes[key] = value.lower() in ("1", "true", "yes")
        else:
            changes[key] = type(current)(float(value))
    return name, dataclasses.replace(base, **changes)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("scenario", type=Path)
    parser.add_argument("--layouts", type=int, default=40)
    parser.add_argument("--seed", type=int, default=15)
    parser.add_argument("--near", type=float, default=None,
                        help="layouts within this distance of `solved` in the unit cube "
                             "(the robustness test's neighbourhood) instead of uniform ones")
    parser.add_argument("--variant", action="append", default=[],
                        help="NAME:key=value,key=value (keys of [simulation])")
    args = parser.parse_args()
    scenario = load_scenario(args.scenario)
    parts = load_parts(scenario)
    engine, cache = Engine(renderer=False), PartCache()
    variants = dict([("file", scenario.settings)]
                    + [parse_variant(v, scenario.settings) for v in args.variant])
    scenarios = {k: dataclasses.replace(scenario, settings=s) for k, s in variants.items()}
    layouts = {"solved": values_from_mapping(scenario, scenario.layouts["solved"])}
    solved = vector_from_values(scenario, layouts["solved"])
    rng = np.random.default_rng(args.seed)
    tries = 0
    while len(layouts) < 1 + args.layouts:
        tries += 1
        if args.near is None:
            vector = rng.random(scenario.dimension)
        else:  # uniform in the ball of radius --near around solved
            direction = rng.normal(size=scenario.dimension)
            radius = args.near * rng.random() ** (1 / scenario.dimension)
            vector = solved + radius * direction / np.linalg.norm(direction)
        values = values_from_vector(scenario, vector)
        if check_validity(make_scene(scenario, values, parts), cache=cache).valid:
            layouts[f"random{tries}"] = values
    simulate(scenario, layouts["solved"], parts, check=False, engine=engine, cache=cache)
    cpu = dict.fromkeys(variants, 0.0)
    results = {k: {} for k in variants}
    for k, (label, values) in enumerate(layouts.items()):
        order = list(variants) if k % 2 == 0 else list(variants)[::-1]
        for v in order:
            start = time.process_time()
            results[v][label] = simulate(scenarios[v], values, parts, check=False,
                                         engine=engine, cache=cache)
            cpu[v] += time.process_time() - start
    n = len(layouts)
    for v in variants:
        mine, base = results[v], results["file"]
        events_moved = sum(mine[k].events != base[k].events for k in layouts)
        moved = [f"{k} {base[k].outcome.value}->{mine[k].outcome.value}" for k in layouts
                 if mine[k].outcome != base[k].outcome]
        successes = sum(r.outcome.value == "success" for r in mine.values())
        print(f"{scenario.name} {v:12s} {cpu[v] / n * 1e3:7.1f} ms/sim "
              f"({cpu[v] / cpu['file']:.3f}x) | successes {successes}/{n} | events moved "
              f"{events_moved}/{n} | outcomes moved {len(moved)}/{n} {moved} | solved: "
              f"{mine['solved'].outcome.value}", flush=True)


if __name__ == "__main__":
    main()
