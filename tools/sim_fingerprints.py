"""Outcome fingerprints of simulations: the reference that a faster simulator must match bit
for bit (outcome, every event's state and time, every body's final pose).

For every shipped scenario: its ``solved`` layout and ``--random`` uniform random valid layouts
(seeded, the same in any checkout). Runs on the code it is imported with, this checkout's or an
older one's (``PYTHONPATH=OLD_TREE``, run from that tree so that its parts are built there):

    uv run python tools/sim_fingerprints.py --out /tmp/new.json
    (cd OLD && PYTHONPATH=$PWD /path/to/venv/bin/python /path/to/tools/sim_fingerprints.py \
        --scenarios /path/to/scenarios --out /tmp/old.json)
    uv run python tools/sim_fingerprints.py --compare /tmp/old.json /tmp/new.json
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sim_api import load_api  # noqa: E402


def fingerprints(path: Path, n_random: int, seed: int) -> dict:
    api = load_api()
    scenario = api.load_scenario(path)
    parts = api.load_parts(scenario)
    rng = np.random.default_rng([seed, *path.stem.encode()])
    layouts = {}
    if "solved" in scenario.layouts:
        layouts["solved"] = api.values_from_mapping(scenario, scenario.layouts["solved"])
    tries = 0
    while sum(k.startswith("random") for k in layouts) < n_random and tries < 200 * n_random:
        tries += 1
        values = api.values_from_vector(scenario, rng.random(scenario.dimension))
        if api.valid(scenario, values, parts):
            layouts[f"random{tries}"] = values
    out = {}
    for name, values in layouts.items():
        final = {}

        def observe(world, t, final=final):
            final["t"] = t
            final["poses"] = {b: world.pose(b).tolist() for b in world.handles}

        r = api.simulate(scenario, values, parts, observer=observe, observe_every=10**9)
        out[name] = {"values": values.tolist(), "outcome": str(r.outcome.value),
                     "events": [[e.name, str(e.state.value if hasattr(e.state, "value")
                                             else e.state), e.time] for e in r.events],
                     "t": final["t"], "poses": final["poses"]}
    return out


def compare(old: dict, new: dict) -> int:
    moved = 0
    for scen in old:
        for name, a in old[scen].items():
            b = new.get(scen, {}).get(name)
            if b is None or a != b:
                moved += 1
                what = "missing" if b is None else ", ".join(
                    k for k in ("values", "outcome", "events", "t", "poses") if a[k] != b[k])
                print(f"{scen}/{name}: {what}"
                      + ("" if b is None else f" ({a['outcome']} -> {b['outcome']})"))
    total = sum(len(v) for v in old.values())
    print(f"{total - moved}/{total} simulations identical")
    return moved


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--scenarios", type=Path, default=Path("scenarios"))
    parser.add_argument("--random", type=int, default=50)
    parser.add_argument("--seed", type=int, default=15)
    parser.add_argument("--out", type=Path)
    parser.add_argument("--only", nargs="*", default=None)
    parser.add_argument("--compare", nargs=2, type=Path)
    args = parser.parse_args()
    if args.compare:
        old, new = (json.loads(p.read_text()) for p in args.compare)
        sys.exit(1 if compare(old, new) else 0)
    result = {p.stem: fingerprints(p, args.random, args.seed)
              for p in sorted(args.scenarios.glob("*.toml"))
              if args.only is None or p.stem in args.only}
    args.out.write_text(json.dumps(result))


if __name__ == "__main__":
    main()
