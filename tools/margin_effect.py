"""What a change of the physics does to outcomes: the shipped scenarios' named layouts and the
six optimised layouts of runs/hand-acceptance built by hand, on fixed draws (common random
numbers), so that two versions of the code can be compared draw by draw.

    nice -n 5 uv run python tools/margin_effect.py --draws 64 --out /tmp/after.json
    PYTHONPATH=/tmp/before nice -n 5 .venv/bin/python tools/margin_effect.py --out /tmp/before.json
    uv run python tools/margin_effect.py --compare /tmp/before.json /tmp/after.json

Each layout file's builds are draws 0..N-1 of seed 0 under the default hand (2 mm, 2 degrees)
and the default physical errors, as ``rgmcad evaluate --layout FILE`` draws them. Results go
to the JSON file as they come (a killed run resumes).
"""

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

SCENARIOS = ("simple", "ballrun", "branching", "causality_switch", "teapot", "long_chain")


def _wilson(k: int, n: int) -> tuple[float, float]:
    if n == 0:
        return 0.0, 1.0
    z, p = 1.959964, k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def measure(draws: int, out: Path, only: list[str]) -> None:
    from rgmcad.runs.hand import DEFAULT_HAND
    from rgmcad.runs.problem import ScenarioContext
    from rgmcad.scene.layout_files import resolve_layout
    from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsDraw
    from rgmcad.sim.engine import Engine
    from rgmcad.sim.run import simulate

    results = json.loads(out.read_text()) if out.is_file() else {}
    engine = Engine(renderer=False)
    for name in only or SCENARIOS:
        context = ScenarioContext.load(f"scenarios/{name}.toml")
        scenario = context.scenario
        key = f"{name}:layouts"
        if key not in results:
            entry = {}
            for layout in scenario.layouts:
                values = resolve_layout(scenario, layout, None)[1]
                r = simulate(scenario, values, context.parts, engine=engine, cache=context.cache)
                steps = max(r.steps, 1)
                entry[layout] = {"outcome": r.outcome.value, "sim_time": r.sim_time,
                                 "steps": r.steps, "build_s": r.build_time,
                                 "step_us": 1e6 * (r.wall_time - r.validity_time - r.build_time)
                                 / steps,
                                 "events": {e.name: e.state.value for e in r.events}}
            results[key] = entry
            out.write_text(json.dumps(results, indent=1))
        key = f"{name}:hand"
        path = Path(f"runs/hand-acceptance/{name}-default-s0/layout.json")
        if key not in results and path.is_file():
            values = resolve_layout(scenario, str(path), None)[1]
            ranges = DEFAULT_HAND.ranges(DEFAULT_PHYSICS)
            outcomes, start = [], time.perf_counter()
            for k in range(draws):
                r = simulate(scenario, values, context.parts, engine=engine, cache=context.cache,
                             physics=PhysicsDraw(ranges, 0, k))
                outcomes.append(r.outcome.value)
            results[key] = {"outcomes": outcomes, "seconds": time.perf_counter() - start}
            out.write_text(json.dumps(results, indent=1))
        context.close()
    engine.close()


def compare(before: Path, after: Path) -> None:
    a, b = json.loads(before.read_text()), json.loads(after.read_text())
    print("| scenario | layout | before | after |\n|---|---|---|---|")
    for key in a:
        if key.endswith(":layouts") and key in b:
            for layout, old in a[key].items():
                new = b[key].get(layout, {})
                print(f"| {key.split(':')[0]} | {layout} | {old['outcome']} ({old['sim_time']:.3f} s)"
                      f" | {new.get('outcome')} ({new.get('sim_time', float('nan')):.3f} s) |")
    print("\n| layout file | before | after | both | only before | only after |\n|---|---|---|---|---|---|")
    for key in a:
        if key.endswith(":hand") and key in b:
            x = np.array([o == "success" for o in a[key]["outcomes"]])
            y = np.array([o == "success" for o in b[key]["outcomes"]])
            n = min(len(x), len(y))
            x, y = x[:n], y[:n]
            cells = []
            for s in (x, y):
                low, high = _wilson(int(s.sum()), n)
                cells.append(f"{s.sum()}/{n} [{100 * low:.0f}, {100 * high:.0f}] %")
            print(f"| {key.split(':')[0]} | {cells[0]} | {cells[1]} | {int((x & y).sum())} | "
                  f"{int((x & ~y).sum())} | {int((~x & y).sum())} |")
    steps = {v: [] for v in ("before", "after")}
    for which, data in (("before", a), ("after", b)):
        for key, entry in data.items():
            if key.endswith(":layouts"):
                steps[which] += [e["step_us"] for e in entry.values() if e["steps"] > 0]
    print("\nmedian step cost over the named layouts: before "
          f"{np.median(steps['before']):.1f} us, after {np.median(steps['after']):.1f} us")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=64)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--only", nargs="*", default=[])
    ap.add_argument("--compare", nargs=2, type=Path)
    args = ap.parse_args()
    if args.compare:
        compare(*args.compare)
    else:
        measure(args.draws, args.out, args.only)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
