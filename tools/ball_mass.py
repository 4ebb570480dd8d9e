"""How far off a ball's mass may be before a layout's built-by-hand figure drops, by
simulation (:mod:`rgmcad.making.ball_mass`), kept beside a layout file (a run's directory)
where the bill of materials (the template's page, the run's report) reads it.

    uv run python tools/ball_mass.py scenarios/ballrun.toml runs/ballrun-s0/layout.json \\
        [--samples 64] [--seed 0]

A named layout (``solved``) is measured and printed, not kept. Prints one JSON object.
"""

import argparse
import json
import sys
import time
from pathlib import Path

from rgmcad.making.ball_mass import measure_ball_mass, read_cached, write_cached
from rgmcad.scene.bodies import load_parts
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.loader import load_scenario
from rgmcad.shipped import scenario_path


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("layout", help="a layout file (kept beside it) or a named layout")
    ap.add_argument("--samples", type=int, default=64, help="builds per mass (default 64)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    path = scenario_path(args.scenario)
    scenario = load_scenario(path)
    _, values = resolve_layout(scenario, args.layout, None)
    folder = Path(args.layout).parent if Path(args.layout).is_file() else None
    if folder is not None and (kept := read_cached(folder, path, values)) is not None \
            and kept.get("samples") == args.samples and kept.get("seed") == args.seed:
        print(json.dumps(kept))
        return 0
    if not any(o.part == "ball" and not o.physical.static for o in scenario.objects.values()):
        print(f"{scenario.name}: no moving ball", file=sys.stderr)
        return 1
    start = time.perf_counter()
    measured = measure_ball_mass(scenario, values, load_parts(scenario),
                                 samples=args.samples, seed=args.seed)
    measured["seconds"] = time.perf_counter() - start
    if folder is not None:
        write_cached(folder, path, values, measured)
    print(json.dumps(measured))
    return 0


if __name__ == "__main__":
    sys.exit(main())
