"""Cost and exactness of the ways of giving hull pieces the part's surface, on a free goblet
(33 hull pieces, one compound) standing on a floor with a ball resting in it.

Variants (monkeypatched into :mod:`rgmcad.sim.shapes`):

* ``default``: hulls as given, pybullet's 1 mm margin on a compound's children (the old way);
* ``margin``: hulls as given, the settings' margin (0.1 mm) on every child;
* ``inset``: hulls inset by the margin and the margin on every child (the chosen way);
* ``tiny``: hulls as given, a 1 um margin on every child.

For each: the face error (a probe sphere's closest distance to the goblet's outer wall and to
its floor, against the exact piece), the build (median of 200 World builds, the OBJ files and
insets already made), the step (median of 10 x 500 steps) and the ball's height after 1 s.

    nice -n 5 uv run python tools/bench_margin.py

With ``--scenarios``: instead, the CPU time (``time.process_time``, which other processes do
not inflate) of building each shipped scenario's ``solved`` world (median of 5 x 20 builds,
engine and part cache reused as in a worker) and of a step (median of 5 x 400 steps), for
comparing two versions of the code (run the older one with ``PYTHONPATH=its/copy``).
"""

import dataclasses
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pybullet as pb

sys.path.insert(0, str(Path(__file__).parent.parent / "tests"))
from _support import scene_of, tiny  # noqa: E402

import rgmcad.sim.shapes as shapes  # noqa: E402
from rgmcad.sim.cache import PartCache  # noqa: E402
from rgmcad.sim.engine import Engine  # noqa: E402
from rgmcad.sim.world import World  # noqa: E402

GOBLET = {"inner_height": 0.11, "top_radius": 0.036, "bottom_radius": 0.025, "wall": 0.002}
OBJECTS = {"floor": {"part": "plane"},
           "g": {"part": "goblet", "params": GOBLET, "mass": 0.05},
           "ball": {"part": "ball", "params": {"radius": 0.01}, "mass": 0.01,
                    "pose": {"z": 0.0125}}}


ORIGINAL = getattr(shapes, "inset_vertices", None), getattr(shapes, "set_margin", None)  # None: older code


def variant(name: str):
    inset, set_margin = ORIGINAL
    if name == "default":
        return (lambda v, m: np.asarray(v, float)), (lambda e, s, m: None), 1e-4
    if name == "margin":
        return (lambda v, m: np.asarray(v, float)), set_margin, 1e-4
    if name == "tiny":
        return (lambda v, m: np.asarray(v, float)), set_margin, 1e-6
    return inset, set_margin, 1e-4


def scenarios() -> None:
    from rgmcad.scene.bodies import load_parts, make_scene
    from rgmcad.scene.design_space import values_from_mapping
    from rgmcad.scene.loader import load_scenario

    engine = Engine(renderer=False)
    print("| scenario | build (CPU) | step (CPU) |\n|---|---|---|")
    for name in ("simple", "ballrun", "branching", "causality_switch", "teapot", "long_chain"):
        scenario = load_scenario(f"scenarios/{name}.toml")
        parts = load_parts(scenario)
        scene = make_scene(scenario, values_from_mapping(scenario, scenario.layouts["solved"]),
                           parts)
        cache = PartCache()
        World(scene, scenario.settings, engine, cache).close()  # files and insets made once
        builds, steps = [], []
        for _ in range(5):
            start = time.process_time()
            for _ in range(20):
                World(scene, scenario.settings, engine, cache).close()
            builds.append((time.process_time() - start) / 20)
            with World(scene, scenario.settings, engine, cache) as world:
                start = time.process_time()
                for _ in range(400):
                    world.step()
                steps.append((time.process_time() - start) / 400)
        print(f"| {name} | {1e3 * statistics.median(builds):.2f} ms | "
              f"{1e6 * statistics.median(steps):.1f} us |")
        cache.close()
    engine.close()


def main() -> int:
    if "--scenarios" in sys.argv:
        scenarios()
        return 0
    sc = tiny(OBJECTS, {"e": {"type": "stopping", "body": "g"}}, duration=1.0)
    scene = scene_of(sc)
    print("| variant | outer wall error | floor error | build | step | ball z after 1 s |")
    print("|---|---|---|---|---|---|")
    for name in ("default", "margin", "inset", "tiny"):
        shapes.inset_vertices, shapes.set_margin, margin = variant(name)
        settings = dataclasses.replace(sc.settings, convex_margin=margin)
        engine, cache = Engine(renderer=False), PartCache()
        errors = []
        with World(scene, settings, engine, cache) as world:
            h = world.handles["g"]
            probe = world.engine.createCollisionShape(pb.GEOM_SPHERE, radius=5e-4)
            # outer wall at half height, a sector's corner (exact on the cone); the floor
            z = 0.056
            radius = 0.025 + (0.036 - 0.025) * z / 0.112
            for at, exact in (([radius + 0.003, 0, z], 0.003 * 0.99522), ([0, 0, 0.006], 0.004)):
                body = world.engine.createMultiBody(0.0, probe, basePosition=at)
                d = min(c[8] for c in pb.getClosestPoints(h.uid, body, 0.02, h.link, -1,
                                                           physicsClientId=world.cid))
                world.engine.removeBody(body)
                errors.append((d + 5e-4 - exact) * 1e3)
        builds = []
        for _ in range(200):
            start = time.perf_counter()
            World(scene, settings, engine, cache).close()
            builds.append(time.perf_counter() - start)
        steps = []
        for _ in range(10):
            with World(scene, settings, engine, cache) as world:
                start = time.perf_counter()
                for _ in range(500):
                    world.step()
                steps.append((time.perf_counter() - start) / 500)
                ball_z = world.pose("ball")[2, 3]
        print(f"| {name} | {errors[0]:+.3f} mm | {errors[1]:+.3f} mm | "
              f"{1e3 * statistics.median(builds):.2f} ms | {1e6 * statistics.median(steps):.1f} us | "
              f"{1e3 * ball_z:.3f} mm |")
        engine.close()
        cache.close()
    shapes.inset_vertices, shapes.set_margin = ORIGINAL
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
